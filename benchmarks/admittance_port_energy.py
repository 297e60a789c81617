"""Is the robot the source of the firm grips' counted oscillations?  The energy at the person's port.

Usage: python benchmarks/admittance_port_energy.py [--operators 30] [--seed-offset 0] [--json]

For every run of benchmarks/admittance_paper.py (human arm, adaptive and constant D 50, 24 and 12
ms) that its oscillation count flags, this computes, over every window of 0.5 s and 1 s in which the
axis moves (RMS speed at least 0.05 rad/s), the energy the person put into the robot, E = sum of
tau_hand * qd * dt (the true hand torque and the measured speed), minus the change of the kinetic
energy the admittance renders, 1/2 I qd^2.  A robot that renders a passive admittance takes in at least
that change; a negative value would mean that the loop's delays made it give energy back (an
instability of the robot's side, Hannaford & Ryu 2002).  Prints the smallest value per run and window.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

WINDOWS = (0.5, 1.0)
MIN_SPEED = 0.05  # rad/s, RMS over the window


def port_margin(data: dict, cycle: float, I: float) -> dict[float, float]:
    """Smallest (port energy - change of rendered kinetic energy) over moving windows, J, per window length."""
    t, te = data["time"], data["tau_ext_true"]
    v = np.gradient(data["q"], t)
    out = {}
    for w in WINDOWS:
        n = int(round(w / cycle))
        vals = [np.sum(te[k - n:k] * v[k - n:k]) * cycle - 0.5 * I * (v[k - 1] ** 2 - v[k - n] ** 2)
                for k in range(n, t.size) if math.sqrt(np.mean(v[k - n:k] ** 2)) >= MIN_SPEED]
        out[w] = float(min(vals)) if vals else math.nan
    return out


def main() -> None:
    import admittance_paper as ap

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--operators", type=int, default=30)
    p.add_argument("--seed-offset", type=int, default=0)
    p.add_argument("--json", action="store_true")
    a = p.parse_args()
    model = ap.controller_model()
    rows = []
    for cycle in (0.024, 0.012):
        for i in range(a.operators):
            seed, grip = a.seed_offset + i, ap.GRIPS[i % 3]
            for damping in ("adaptive", "constant"):
                m, run = ap.run_one(model, seed, damping, 50.0, cycle, grip=grip, with_run=True)
                if m["oscillating"]:
                    rows.append({"cycle": cycle, "seed": seed, "grip": grip, "damping": damping,
                                 **{f"min_{w:g}s": v for w, v in port_margin(run.data, cycle, run.config.I).items()}})
    if a.json:
        json.dump(rows, sys.stdout)
        print()
        return
    print(f"runs counted as oscillating, operators {a.seed_offset}-{a.seed_offset + a.operators - 1}: smallest port "
          f"energy minus the change of rendered kinetic energy over moving windows (J; negative: the robot gave energy back)")
    print(f"{'cycle':>6} {'seed':>5} {'grip':>9} {'damping':>9} | {'0.5 s':>7} {'1 s':>7}")
    for r in rows:
        print(f"{r['cycle'] * 1000:4.0f}ms {r['seed']:5d} {r['grip']:>9} {r['damping']:>9} | {r['min_0.5s']:7.2f} "
              f"{r['min_1s']:7.2f}")


if __name__ == "__main__":
    main()
