"""Short recordings of a real robot: does `fit --robot` stay sane on a few seconds of data?

Random cuts (``--cuts`` per recording, 150-500 samples: 0.7-2.5 s at about 200 Hz) of the LWR4+
recordings lwr4_1-3, each fitted with the defaults. Per cut: refused (a clear error: too little
motion), did not converge, or fitted; of the fitted, the largest friction/offset/spring/ripple term
(N·m) and the largest relative error on the cut. A short log leaves most of the robot undetermined
(the fit warns so); what it must not do is write terms of 1e5 N·m that cancel where the joint moved
and not elsewhere (before the extras' ridge, 17 of 18 cuts of seed 1 did).

Run: python benchmarks/robot_fit_short_cuts.py [--seed 1] [--cuts 6] [--json]
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
DATA = HERE.parent.parent / "shared" / "datasets" / "lwr4"
RUNAWAY = 1e3  # N·m: no LWR4+ joint's friction or offset comes near it (its torques stay under 60 N·m)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--cuts", type=int, default=6, help="cuts per recording")
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args(argv)
    if not DATA.is_dir():
        print(f"no LWR4+ data at {DATA}", file=sys.stderr)
        return 2
    from kukaid.errors import KukaidError
    from kukaid.identify.robot_fit import fit_robot
    from kukaid.logs import read_log
    from kukaid.models.robot import RobotModel

    robot = RobotModel(DATA / "kuka_lwr4.urdf")
    rng = np.random.default_rng(a.seed)
    rows = []
    for f in (1, 2, 3):
        log = read_log(DATA / f"lwr4_{f}.csv")
        for _ in range(a.cuts):
            n = int(rng.integers(150, 500))
            start = int(rng.integers(0, log.n_samples - n))
            row = {"recording": f"lwr4_{f}", "start": start, "samples": n}
            try:
                p = fit_robot([log.select(slice(start, start + n))], robot)
            except KukaidError as e:
                row["outcome"] = "did not converge" if "converge" in str(e) else "refused"
                row["why"] = str(e)[:120]
            else:
                row["outcome"] = "fitted"
                row["largest_term"] = max(abs(v) for v in p["friction"]["values"].values())
                row["largest_rel_error"] = max(p["metrics"]["relative_error_fit"])
            rows.append(row)
            print(".", end="", file=sys.stderr, flush=True)
    print(file=sys.stderr)
    fitted = [r for r in rows if r["outcome"] == "fitted"]
    summary = {"cuts": len(rows), "fitted": len(fitted),
               "refused": sum(r["outcome"] == "refused" for r in rows),
               "did_not_converge": sum(r["outcome"] == "did not converge" for r in rows),
               "runaway": sum(r["largest_term"] > RUNAWAY for r in fitted),
               "largest_term": max((r["largest_term"] for r in fitted), default=float("nan")),
               "median_largest_rel_error": float(np.median([r["largest_rel_error"] for r in fitted])) if fitted else None}
    if a.json:
        print(json.dumps({"seed": a.seed, "summary": summary, "rows": rows}, indent=1))
        return 0
    print(f"{'recording':<10}{'start':>7}{'samples':>8}  {'outcome':<17}{'largest term N·m':>17}{'largest rel. error':>19}")
    for r in rows:
        if r["outcome"] == "fitted":
            print(f"{r['recording']:<10}{r['start']:>7}{r['samples']:>8}  {r['outcome']:<17}{r['largest_term']:>17.4g}"
                  f"{100 * r['largest_rel_error']:>18.1f}%")
        else:
            print(f"{r['recording']:<10}{r['start']:>7}{r['samples']:>8}  {r['outcome']:<17}  {r['why']}")
    print(f"\n{summary['fitted']} of {summary['cuts']} cuts fitted ({summary['refused']} refused, "
          f"{summary['did_not_converge']} did not converge); {summary['runaway']} with a term beyond {RUNAWAY:g} N·m; "
          f"largest term {summary['largest_term']:.4g} N·m")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
