"""Real multi-axis data (KUKA LWR4+): per axis, fit and diagnose on one recording, validate both
models on another (``kukaid validate``): the refined model must never be worse than the model it
started from.

    python benchmarks/diagnose_lwr4.py [--fit lwr4_1] [--other lwr4_3] [--axes 1-7] [--json]

Prints per axis: the fit's warnings (single-axis adequacy), the effects diagnose named, and the
held-out RMSE and relative error of the fitted and the refined model on the other recording.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
DATA = HERE.parents[1] / "shared" / "datasets" / "lwr4"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fit", default="lwr4_1")
    ap.add_argument("--other", default="lwr4_3")
    ap.add_argument("--axes", default="1-7")
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args(argv)
    if not (DATA / f"{a.fit}.csv").exists():
        print(f"{DATA} is not present", file=sys.stderr)
        return 1
    from kukaid.diagnose.validate import validate
    from kukaid.diagnose.workflow import diagnose
    from kukaid.identify import fit_axis
    from kukaid.logs import read_log

    lo, hi = (int(x) for x in a.axes.split("-")) if "-" in a.axes else (int(a.axes), int(a.axes))
    fit_log, other = read_log(DATA / f"{a.fit}.csv"), read_log(DATA / f"{a.other}.csv")
    rows = []
    for ax in range(lo, hi + 1):
        t0 = time.perf_counter()
        p = fit_axis(logs=[fit_log], axis=ax)
        d = diagnose(p, [fit_log], axis=ax)
        v0 = validate(p, [other], axis=ax)[ax]
        v1 = validate(d.params, [other], axis=ax)[ax]
        rows.append({"axis": ax, "named": d.names, "ambiguous": [x["candidates"] for x in d.ambiguous],
                     "rejected": {r["name"]: r["reason"] for r in d.rejected}, "fit_adequate": p["metrics"]["single_axis_adequate"],
                     "at_bound": [b["name"] for b in p["metrics"]["at_bound"]],
                     "fit": v0.to_json(), "refined": v1.to_json(), "never_worse": v1.rmse <= v0.rmse * (1 + 1e-9),
                     "seconds": time.perf_counter() - t0})
    if a.json:
        print(json.dumps(rows, indent=2))
        return 0
    print(f"fit and diagnose on {a.fit}, validate on {a.other} (RMSE N*m, relative error)")
    print(f"{'axis':<5} {'named':<28} {'fit RMSE':>9} {'rel':>7} {'refined':>9} {'rel':>7}  never worse")
    for r in rows:
        print(f"A{r['axis']:<4} {','.join(r['named']) or '-':<28} {r['fit']['rmse']:>9.4g} "
              f"{100 * r['fit']['rel_error']:>6.1f}% {r['refined']['rmse']:>9.4g} {100 * r['refined']['rel_error']:>6.1f}%"
              f"  {'yes' if r['never_worse'] else 'NO'}")
    print(f"never worse on {sum(r['never_worse'] for r in rows)}/{len(rows)} axes")
    return 0


if __name__ == "__main__":
    sys.exit(main())
