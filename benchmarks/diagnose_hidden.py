"""Hidden effects on simulated data drawn independently of the toolkit's simulator.

    python benchmarks/diagnose_hidden.py [--seeds 5] [--json]

Each case is one log of a single revolute axis written here from scratch (not ``kukaid.sim``):
a random multi-sine excitation (not the paper's sweep and sine), random rigid-body and friction
parameters, white torque noise, and at most one hidden effect of a random size between 2.5 and
5 noise sigmas: a constant offset, My sin q, a position ripple (order drawn so the range holds at
least 1.5 periods), Coulomb friction drifting in time with **no temperature channel** (a 150 s
log), load-dependent Coulomb friction, a Stribeck rise (fitted with a Coulomb + viscous model).
The model is fitted with ``fit_axis`` (Coulomb + viscous, gravity cos), then diagnosed.  Prints,
per effect, how often the right effect is named first and how often anything else is named;
on clean logs, how often anything is named.
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

EFFECTS = ("torque_offset", "gravity_sine", "position_ripple", "thermal_drift", "load_dependent_friction",
           "stribeck", None)


def make_log(effect: str | None, seed: int, fs: float = 250.0, T: float = 150.0):
    from kukaid.logs import AxisLog

    rng = np.random.default_rng(1000 + seed)
    t = np.arange(0.0, T, 1.0 / fs)
    q, qd, qdd = multisine(rng, t, (-0.5, 0.5), (0.04, 0.4), (0.15, 0.5))
    Izz, Mx = rng.uniform(0.5, 3.0), rng.uniform(5, 40) * rng.choice([-1, 1])
    Fc, Fv = rng.uniform(3, 15), rng.uniform(2, 12)
    noise = rng.uniform(0.2, 0.8)
    size = rng.uniform(2.5, 5.0) * noise
    s = np.sign(qd)
    fc_t = np.full(t.size, Fc)
    extra = np.zeros(t.size)
    if effect == "torque_offset":
        extra = size * rng.choice([-1, 1]) * np.ones(t.size)
    elif effect == "gravity_sine":
        extra = size * rng.choice([-1, 1]) * np.sin(q)
    elif effect == "position_ripple":
        R = float(np.ptp(q))
        n = rng.uniform(max(1.5 * 2 * np.pi / R, 3.0), 25.0)
        extra = size * np.sin(n * q + rng.uniform(0, 2 * np.pi))
    elif effect == "thermal_drift":  # Coulomb friction changes by `size` over the log, in time
        fc_t = Fc + size * rng.choice([-1, 1]) * t / T
    elif effect == "load_dependent_friction":
        extra = size * np.abs(np.cos(q)) * s
    elif effect == "stribeck":
        vs = rng.uniform(0.03, 0.15)
        extra = size * s * np.exp(-(np.abs(qd) / vs) ** rng.choice([1.0, 2.0]))
    tau = Izz * qdd + Mx * np.cos(q) + fc_t * s + Fv * qd + extra + noise * rng.standard_normal(t.size)
    return AxisLog(t, q[:, None], tau[:, None], axes=(2,), attrs={"source_file": f"{effect or 'clean'}-{seed}"})


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args(argv)
    from kukaid.diagnose.workflow import diagnose
    from kukaid.identify import fit_axis

    rows = []
    for eff in EFFECTS:
        for seed in range(a.seeds):
            log = make_log(eff, seed)
            t0 = time.perf_counter()
            p = fit_axis(logs=[log], friction_model="coulomb-viscous")
            d = diagnose(p, [log])
            rows.append({"effect": eff or "clean", "seed": seed, "named": d.names,
                         "ambiguous": [x["candidates"] for x in d.ambiguous], "seconds": time.perf_counter() - t0})
    summary = {}
    for eff in EFFECTS:
        key = eff or "clean"
        rs = [r for r in rows if r["effect"] == key]
        right = sum(bool(r["named"]) and r["named"][0] == eff for r in rs) if eff else None
        wrong = sum(any(n != eff for n in r["named"]) for r in rs)
        summary[key] = {"cases": len(rs), "right_first": right, "named_something_else": wrong}
    hidden = [v for k, v in summary.items() if k != "clean"]
    rate = sum(v["right_first"] for v in hidden) / max(1, sum(v["cases"] for v in hidden))
    if a.json:
        print(json.dumps({"rows": rows, "summary": summary, "right_rate": rate}, indent=2))
        return 0
    print(f"{'hidden effect':<25} {'cases':>5} {'right first':>12} {'other named':>12}")
    for k, v in summary.items():
        rf = "-" if v["right_first"] is None else str(v["right_first"])
        print(f"{k:<25} {v['cases']:>5} {rf:>12} {v['named_something_else']:>12}")
    print(f"right effect named first: {100 * rate:.0f} % of {sum(v['cases'] for v in hidden)} hidden-effect cases; "
          f"clean logs with anything named: {summary['clean']['named_something_else']}/{summary['clean']['cases']}")
    for r in rows:
        if (r["effect"] == "clean" and r["named"]) or (r["effect"] != "clean" and (not r["named"] or r["named"][0] != r["effect"])):
            print(f"  miss: {r['effect']} seed {r['seed']}: named {r['named']}, ambiguous {r['ambiguous']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
