"""Cost of fit and diagnose against the number of samples: linear, not quadratic.

    python benchmarks/diagnose_scaling.py [--repeats 4 16] [--hour] [--json]

1. EMPS (real, 1 kHz, 24,841 samples) repeated k times end to end (one long log): ``kukaid fit``
   (Coulomb + viscous, no gravity, no offset) and ``kukaid diagnose`` timed for each k; the ratio
   of the times for 16x and 4x (acceptance: at most 5.5; 4.0 is exactly linear).
2. ``--hour``: a one-hour single-axis log at 1 kHz (3.6 million samples), simulated here with a
   multi-sine excitation, Stribeck friction, gravity and white torque noise (no hidden effect),
   fitted and diagnosed (target: diagnosed in under 2 minutes on 2 cores).
Times are wall-clock seconds on this machine; nothing is asserted.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
EMPS = HERE.parents[1] / "shared" / "datasets" / "emps" / "DATA_EMPS.mat"


def repeated(log, k: int):
    """The log repeated ``k`` times, time continuing."""
    from kukaid.logs import AxisLog

    t = log.time - log.time[0]
    dt = float(np.median(np.diff(t)))
    T = t[-1] + dt
    time_ = np.concatenate([t + i * T for i in range(k)])
    rep = lambda x: None if x is None else np.concatenate([x] * k)  # noqa: E731
    return AxisLog(time_, rep(log.q), rep(log.tau), axes=log.axes, q_cmd=rep(log.q_cmd), joint=log.joint,
                   attrs={**log.attrs, "source_file": f"EMPS x{k}"})


def hour_log(seed: int = 7, fs: float = 1000.0, T: float = 3600.0):
    """One hour of a single revolute axis at ``fs``: multi-sine motion, Stribeck + viscous friction,
    Izz qdd + Mx cos q, white torque noise (values unrelated to any data set)."""
    from kukaid.logs import AxisLog

    rng = np.random.default_rng(seed)
    t = np.arange(0.0, T, 1.0 / fs)
    q = np.zeros(t.size)
    qd = np.zeros(t.size)
    qdd = np.zeros(t.size)
    for f, a in zip(rng.uniform(0.05, 0.6, 5), rng.uniform(0.1, 0.4, 5)):
        ph = rng.uniform(0, 2 * np.pi)
        w = 2 * np.pi * f
        q += a * np.sin(w * t + ph)
        qd += a * w * np.cos(w * t + ph)
        qdd -= a * w * w * np.sin(w * t + ph)
    Fc, Fs, vs, dl, Fv, Izz, Mx = 7.3, 9.1, 0.04, 1.3, 5.2, 1.1, 17.0
    fr = (Fc + (Fs - Fc) * np.exp(-(np.abs(qd) / vs) ** dl)) * np.sign(qd) + Fv * qd
    tau = Izz * qdd + Mx * np.cos(q) + fr + 0.3 * rng.standard_normal(t.size)
    return AxisLog(t, q[:, None], tau[:, None], axes=(3,), attrs={"source_file": "one hour, simulated"})


def timed(fn):
    t0 = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, nargs="*", default=[4, 16], help="EMPS repeats (none: skip)")
    ap.add_argument("--hour", action="store_true", help="also the one-hour 1 kHz simulated log")
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args(argv)
    from kukaid.diagnose.workflow import diagnose
    from kukaid.identify import fit_axis
    from kukaid.logs import read_mat

    rows = []
    if EMPS.exists():
        base = read_mat(EMPS, time="t", q="qm", tau="vir", tau_scale_var="gtau", joint="prismatic", q_cmd="qg")
        for k in a.repeats:
            log = repeated(base, k)
            p, tf = timed(lambda: fit_axis(logs=[log], friction_model="coulomb-viscous", gravity="none", offset=False))
            d, td = timed(lambda: diagnose(p, [log]))
            rows.append({"case": f"EMPS x{k}", "samples": log.n_samples, "fit_s": tf, "diagnose_s": td,
                         "named": d.names})
    else:
        print(f"{EMPS} not present: EMPS rows skipped", file=sys.stderr)
    if a.hour:
        log = hour_log()
        p, tf = timed(lambda: fit_axis(logs=[log]))
        d, td = timed(lambda: diagnose(p, [log]))
        rows.append({"case": "1 h at 1 kHz (sim)", "samples": log.n_samples, "fit_s": tf, "diagnose_s": td,
                     "named": d.names})
    ratio = None
    emps = {r["case"]: r for r in rows}
    if "EMPS x4" in emps and "EMPS x16" in emps:
        ratio = emps["EMPS x16"]["diagnose_s"] / emps["EMPS x4"]["diagnose_s"]
    if a.json:
        print(json.dumps({"rows": rows, "diagnose_ratio_16_over_4": ratio}, indent=2))
        return 0
    print(f"{'case':<22} {'samples':>9} {'fit s':>8} {'diagnose s':>11}  named")
    for r in rows:
        print(f"{r['case']:<22} {r['samples']:>9d} {r['fit_s']:>8.2f} {r['diagnose_s']:>11.2f}  {', '.join(r['named']) or '-'}")
    if ratio is not None:
        print(f"diagnose time 16x / 4x = {ratio:.2f} (linear: 4.0; acceptance: <= 5.5)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
