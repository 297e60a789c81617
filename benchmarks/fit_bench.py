"""IPOPT (CasADi) against two scipy peers on the same Stribeck + rigid-body least-squares problem.

Data: virtual-KR-C4 friction and inertia logs (truth away from the paper, default noise), the
joint model's dynamic samples.  All solvers get the same start (the variable-projection grid
optimum), the same bounds and the same scaled variables (linear parameters over their start
magnitude, log vs, delta); scipy gets the analytic Jacobian (and the Gauss-Newton Hessian for
trust-constr), IPOPT the Gauss-Newton Hessian kukaid gives it.  Printed: the time of the shared
start, the wall time of each solve (IPOPT's includes building the CasADi problem) and the final
cost 0.5 sum r².
Then the full `kukaid fit` of the demo data (friction + inertia + presliding logs), as a
subprocess, wall time.

Run: python benchmarks/fit_bench.py [--repeat 3]
"""
from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np


def problem(seed: int = 7):
    from kukaid import excite
    from kukaid.identify import preprocess
    from kukaid.identify.dynamic import _columns
    from kukaid.sim import SimConfig, VirtualKRC4

    cfg = SimConfig().replace(Fc=12.3, Fs=15.1, vs=0.055, delta=1.4, Fv=9.7, Izz=1.73, Mx=24.6)
    preps = [preprocess(VirtualKRC4(cfg, seed=seed).run(excite.generate(k)), 3) for k in ("friction", "inertia")]
    ys, As, vs = [], [], []
    for pr in preps:
        names, A = _columns(pr, "stribeck", "cos", False, None, pr.dynamic)
        ys.append(pr.tau[pr.dynamic])
        As.append(A)
        vs.append(pr.qd[pr.dynamic])
    return np.concatenate(ys), np.vstack(As), np.concatenate(vs), names


def shared_start(y, A, v, names):
    """Bounds and the variable-projection start every solver gets (timed on its own)."""
    from kukaid.identify.stribeck_fit import _clip_into, _merge_bounds, default_bounds, vp_start

    t0 = time.perf_counter()
    bnd = _merge_bounds(default_bounds(y, v, names), None)
    allnames = [*names, "dF", "vs", "delta"]
    lo = np.array([bnd[k][0] for k in allnames])
    hi = np.array([bnd[k][1] for k in allnames])
    p0 = _clip_into(vp_start(y, A, v, bnd)[0], lo, hi)
    return p0, lo, hi, time.perf_counter() - t0


def run_ipopt(y, A, v, p0, lo, hi):
    """kukaid's solver: builds the CasADi NLP (and its Hessian) and runs IPOPT."""
    from kukaid.identify.stribeck_fit import _ipopt, prediction_and_jac

    t0 = time.perf_counter()
    ps, status, ok, _, _ = _ipopt(y, A, v, p0, lo, hi)
    dt = time.perf_counter() - t0
    assert ok, status
    r = y - prediction_and_jac(A, v, ps)[0]
    return dt, 0.5 * float(r @ r), ps


def scipy_peers(y, A, v, p0, lo, hi):
    from scipy.optimize import Bounds, least_squares, minimize

    from kukaid.identify.stribeck_fit import prediction_and_jac

    m = A.shape[1] + 1
    scale = np.maximum(np.abs(p0[:m]), 1e-3)

    def to_p(x):
        return np.r_[x[:m] * scale, np.exp(x[m]), x[m + 1]]

    def dp_dx(x):
        return np.r_[scale, np.exp(x[m]), 1.0]

    def res(x):
        return y - prediction_and_jac(A, v, to_p(x))[0]

    def jac(x):
        return -prediction_and_jac(A, v, to_p(x))[1] * dp_dx(x)

    x0 = np.r_[p0[:m] / scale, np.log(p0[m]), p0[m + 1]]
    xlo = np.r_[lo[:m] / scale, np.log(lo[m]), lo[m + 1]]
    xhi = np.r_[hi[:m] / scale, np.log(hi[m]), hi[m + 1]]
    out = {}
    t0 = time.perf_counter()
    r = least_squares(res, x0, jac=jac, bounds=(xlo, xhi), method="trf", x_scale="jac", ftol=1e-12, xtol=1e-12,
                      gtol=1e-10)
    out["scipy least_squares (trf, bounds)"] = (time.perf_counter() - t0, 0.5 * float(res(r.x) @ res(r.x)),
                                                to_p(r.x))

    def f(x):
        rr = res(x)
        return 0.5 * float(rr @ rr)

    def g(x):
        return jac(x).T @ res(x)

    def h(x):
        J = jac(x)
        return J.T @ J

    t0 = time.perf_counter()
    r2 = minimize(f, x0, jac=g, hess=h, method="trust-constr", bounds=Bounds(xlo, xhi),
                  options={"gtol": 1e-10, "xtol": 1e-12, "maxiter": 2000})
    out["scipy minimize (trust-constr)"] = (time.perf_counter() - t0, f(r2.x), to_p(r2.x))
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=3)
    a = ap.parse_args()
    y, A, v, names = problem()
    allnames = [*names, "Fs-Fc", "vs", "delta"]
    rows = {}
    t_start = []
    for _ in range(a.repeat):
        p0, lo, hi, ts = shared_start(y, A, v, names)
        t_start.append(ts)
        t, c, p = run_ipopt(y, A, v, p0, lo, hi)
        rows.setdefault("CasADi + IPOPT (kukaid)", []).append((t, c, p))
        for k, val in scipy_peers(y, A, v, p0, lo, hi).items():
            rows.setdefault(k, []).append(val)
    print(f"Stribeck + Izz/Mx joint fit, {y.size} dynamic samples, {len(allnames)} parameters, best of {a.repeat}.\n"
          f"Every solver starts from the same variable-projection optimum (bounds and grid: {min(t_start):.3f} s, "
          f"not included below); IPOPT's time includes building the CasADi problem.")
    print(f"{'solver':<36} {'time s':>8} {'final cost 0.5*sum r^2':>24}")
    best = {}
    for k, vals in rows.items():
        t = min(x[0] for x in vals)
        c = vals[-1][1]
        best[k] = (t, c, vals[-1][2])
        print(f"{k:<36} {t:>8.3f} {c:>24.10g}")
    print("parameters: " + ", ".join(allnames))
    for k, (_, _, p) in best.items():
        print(f"  {k:<34} " + " ".join(f"{x:.6g}" for x in p))
    # full kukaid fit of the demo data
    with tempfile.TemporaryDirectory() as d:
        d = Path(d)
        from kukaid import excite
        from kukaid.logs import write_hdf5
        from kukaid.sim import SimConfig, VirtualKRC4

        for i, k in enumerate(("friction", "inertia", "presliding")):
            write_hdf5(VirtualKRC4(SimConfig(), seed=1 + i).run(excite.generate(k)), d / f"{k}.h5")
        times = []
        for _ in range(a.repeat):
            t0 = time.perf_counter()
            r = subprocess.run([sys.executable, "-m", "kukaid_cli.main", "fit", "--friction", str(d / "friction.h5"), "--inertia", str(d / "inertia.h5"),
                                "--presliding", str(d / "presliding.h5"), "-o", str(d / "params.json")],
                               capture_output=True, text=True)
            times.append(time.perf_counter() - t0)
            if r.returncode != 0:
                print(r.stderr, file=sys.stderr)
                sys.exit(1)
        print(f"\nfull `kukaid fit` of the demo data (friction + inertia + presliding), wall time: "
              f"best {min(times):.2f} s, median {np.median(times):.2f} s (target < 3 s)")


if __name__ == "__main__":
    main()
