"""A hidden reversal transient that backlash and pre-sliding friction explain alike, on logs drawn
independently of the toolkit's simulator; the gap measured on a recording the diagnosis never saw.

    python benchmarks/diagnose_ambiguous.py [--seeds 6] [--clean] [--json]

Each case is five recordings of one revolute axis written here from scratch (not ``kukaid.sim``,
not the diagnosis' own effect columns): random multi-sine excitations (a new draw per recording),
random rigid-body and friction parameters, white torque noise, and one reversal transient of one
of two physical kinds, alternating with the seed:

* ``dahl``: a part Fd of the Coulomb friction Fc (2.5-5 noise sigmas) follows Dahl's law,
  dF/dq = (Fd / x0) (1 - F / (Fd sgn qd)), integrated exactly step by step (x0, the pre-sliding
  displacement, drawn in 4-12 mrad); the rest switches with the sign of the velocity;
* ``impact``: a rise-and-decay pulse in time after every reversal, A (1 - exp(-t / tr)) exp(-t / T)
  with T drawn in 0.05-0.2 s and tr = T / 3 (the load hitting the other flank of a gear's play),
  A against the motion, 5-10 noise sigmas.

With one position sensor per axis the two mechanisms give the same transient.  The model is fitted
(``fit_axis``, Coulomb + viscous, gravity cos) on the first three recordings and diagnosed on them
(leave one recording out); the last two are held out: the fitted and the diagnosed parameter
files each predict them (the diagnosis' own comparison: same filter, same compared rows, no refit) and
the gap is their pooled RMSE against their noise floor.  Reported per case: what was named, what the
diagnosis says is undetermined between which candidates, held-out RMSE / noise floor before and
after, and the share of the held-out gap (RMSE - floor) the diagnosis closed.  ``--clean`` adds,
per seed, the same axis without the transient: nothing should be named there.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))  # multisine.py, also under a test
from multisine import multisine  # noqa: E402

KINDS = ("dahl", "impact")


def truth(seed: int, clean: bool = False) -> dict:
    """The axis and its hidden transient for ``seed`` (drawn away from the toolkit's defaults);
    ``clean``: the same axis without it."""
    rng = np.random.default_rng(7000 + seed)
    kind = "clean" if clean else KINDS[seed % 2]
    t = {"kind": kind, "Izz": rng.uniform(0.5, 3.0), "Mx": rng.uniform(5, 40) * rng.choice([-1, 1]),
         "Fc": rng.uniform(3, 12), "Fv": rng.uniform(2, 10), "noise": rng.uniform(0.2, 0.6)}
    if kind == "clean":
        pass
    elif kind == "dahl":
        t["x0"] = rng.uniform(4e-3, 12e-3)
        t["Fd"] = rng.uniform(2.5, 5.0) * t["noise"]  # the part of Fc that builds up (Dahl)
    else:
        t["T"] = rng.uniform(0.05, 0.2)
        t["A"] = -rng.uniform(5.0, 10.0) * t["noise"]  # lags the Coulomb step, as play does
    return t


def _reversals(qd: np.ndarray, thr: float = 1e-3) -> tuple[np.ndarray, np.ndarray]:
    s = np.where(qd > thr, 1, np.where(qd < -thr, -1, 0))
    idx = np.flatnonzero(s)
    ch = np.flatnonzero(s[idx][1:] != s[idx][:-1]) + 1
    return idx[ch], s[idx][ch].astype(float)


def make_log(tr: dict, seed: int, k: int, fs: float = 250.0, T: float = 40.0):
    """Recording ``k`` of case ``seed`` with truth ``tr``."""
    from kukaid.logs import AxisLog

    rng = np.random.default_rng(100 * seed + k + 17)
    t = np.arange(0.0, T, 1.0 / fs)
    q, qd, qdd = multisine(rng, t, (-0.4, 0.4), (0.08, 0.5), (0.08, 0.3))
    s = np.sign(qd)
    fric = tr["Fc"] * s
    if tr["kind"] == "dahl":  # exact for a constant direction within a step
        F = np.zeros(t.size)
        F[0] = tr["Fd"] * s[0]
        for i in range(1, t.size):
            d = q[i] - q[i - 1]
            target = tr["Fd"] * np.sign(d) if d != 0 else F[i - 1]
            F[i] = target + (F[i - 1] - target) * np.exp(-abs(d) / tr["x0"])
        fric = (tr["Fc"] - tr["Fd"]) * s + F
    elif tr["kind"] == "impact":
        idx, new = _reversals(qd)
        bounds = list(idx) + [t.size]
        for j, i in enumerate(idx):
            x = t[i:bounds[j + 1]] - t[i]
            fric[i:bounds[j + 1]] += new[j] * tr["A"] * (1 - np.exp(-3 * x / tr["T"])) * np.exp(-x / tr["T"])
    tau = (tr["Izz"] * qdd + tr["Mx"] * np.cos(q) + fric + tr["Fv"] * qd
           + tr["noise"] * rng.standard_normal(t.size))
    return AxisLog(t, q[:, None], tau[:, None], axes=(2,),
                   attrs={"source_file": f"{tr['kind']}-{seed}-rec{k + 1}"})


def held_out_gap(params: dict, logs) -> tuple[float, float]:
    """(RMSE, noise floor) of the model of ``params`` on ``logs`` (pooled) in the diagnosis' comparison."""
    from kukaid.diagnose.workflow import diagnose

    d = diagnose(params, list(logs), max_steps=0)
    return d.rmse_before, d.noise_floor


def run_case(seed: int, clean: bool = False) -> dict:
    from kukaid.diagnose.workflow import diagnose
    from kukaid.identify import fit_axis

    tr = truth(seed, clean)
    logs = [make_log(tr, seed, k) for k in range(5)]
    train, test = logs[:3], logs[3:]
    t0 = time.perf_counter()
    fitted = fit_axis(logs=train, friction_model="coulomb-viscous")
    d = diagnose(fitted, train)
    secs = time.perf_counter() - t0
    r0, floor = held_out_gap(fitted, test)
    r1, _ = held_out_gap(d.params, test)
    closed = (r0 - r1) / (r0 - floor) if r0 > floor else float("nan")
    undet = [x for x in d.ambiguous if x.get("modelled_as")]
    return {"seed": seed, "kind": tr["kind"], "named": d.names,
            "ambiguous": [x["candidates"] for x in d.ambiguous],
            "undetermined": [{"candidates": x["candidates"], "modelled_as": x["modelled_as"],
                              "settled_by": x.get("settled_by", "")} for x in undet],
            "held_out_rmse_fit": r0, "held_out_rmse_diagnosed": r1, "held_out_floor": floor,
            "ratio_fit": r0 / floor, "ratio_diagnosed": r1 / floor, "gap_closed": closed,
            "in_sample_ratio": d.rmse_after / d.noise_floor, "seconds": secs,
            "truth": {k: (float(v) if not isinstance(v, str) else v) for k, v in tr.items()}}


def both_named(r: dict) -> bool:
    """Both reversal mechanisms named for the term the diagnosis added."""
    return any(set(x["candidates"]) == {"backlash", "presliding"} and x["modelled_as"] in r["named"]
               for x in r["undetermined"])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=6)
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--clean", action="store_true", help="also the same axes without the transient (nothing "
                                                            "should be named)")
    a = ap.parse_args(argv)
    rows = [run_case(seed) for seed in range(a.seeds)]
    clean = [run_case(seed, clean=True) for seed in range(a.seeds)] if a.clean else []
    closed = [r["gap_closed"] for r in rows]
    summary = {"cases": len(rows), "mean_gap_closed": float(np.nanmean(closed)),
               "median_gap_closed": float(np.nanmedian(closed)),
               "min_gap_closed": float(np.nanmin(closed)),
               "mean_ratio_fit": float(np.mean([r["ratio_fit"] for r in rows])),
               "mean_ratio_diagnosed": float(np.mean([r["ratio_diagnosed"] for r in rows])),
               "both_named": sum(both_named(r) for r in rows),
               "by_kind": {k: {"cases": len(rs), "mean_gap_closed": float(np.nanmean([r["gap_closed"] for r in rs])),
                               "mean_ratio_fit": float(np.mean([r["ratio_fit"] for r in rs])),
                               "mean_ratio_diagnosed": float(np.mean([r["ratio_diagnosed"] for r in rs]))}
                           for k in KINDS for rs in [[r for r in rows if r["kind"] == k]] if rs},
               "clean_cases": len(clean), "clean_named": sum(bool(r["named"]) for r in clean)}
    if a.json:
        print(json.dumps({"rows": rows, "clean": clean, "summary": summary}, indent=2))
        return 0
    print(f"{'case':<10} {'named':<24} {'undetermined (modelled as)':<38} {'held-out RMSE/floor':>20} {'gap closed':>10}")
    for r in rows:
        und = "; ".join(f"{' or '.join(x['candidates'])} ({x['modelled_as']})" for x in r["undetermined"]) or "-"
        print(f"{r['kind'] + '-' + str(r['seed']):<10} {', '.join(r['named']) or '-':<24} {und:<38} "
              f"{r['ratio_fit']:>9.2f} -> {r['ratio_diagnosed']:<7.2f} {100 * r['gap_closed']:>9.0f} %")
    print(f"held-out gap closed: mean {100 * summary['mean_gap_closed']:.0f} %, median "
          f"{100 * summary['median_gap_closed']:.0f} % over {len(rows)} cases (RMSE / floor "
          f"{summary['mean_ratio_fit']:.2f} -> {summary['mean_ratio_diagnosed']:.2f}); both mechanisms named in "
          f"{summary['both_named']}/{len(rows)}")
    for k, v in summary["by_kind"].items():
        print(f"  {k}: {v['cases']} cases, RMSE / floor {v['mean_ratio_fit']:.2f} -> {v['mean_ratio_diagnosed']:.2f}, "
              f"gap closed {100 * v['mean_gap_closed']:.0f} % (mean)")
    if clean:
        print(f"clean axes (no transient): anything named in {summary['clean_named']}/{len(clean)}"
              + "".join(f"; {r['kind']}-{r['seed']} named {', '.join(r['named'])}" for r in clean if r["named"]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
