"""Monte-Carlo efficiency of the joint fit: RMSE of Izz, Mx, Fc, Fv against the Cramér-Rao bound.

One noise-free virtual-KR-C4 run of the friction and inertia experiments (truth away from the
paper's values); then ``--n`` (default 200) seeded realisations of white torque noise
(``--sigma`` 0.5 N·m, the KRC default) added to its torque, each fitted by the default pipeline
(5 Hz zero-phase filter, joint Stribeck + Izz/Mx fit with IPOPT).

The Cramér-Rao bound is ``sigma^2 (J^T J)^-1`` with J the model's Jacobian over the same
(dynamic-mode) samples, evaluated at the noise-free fit: the smallest covariance any unbiased
estimator can reach from these samples with white noise of that sigma.  The random error of
the estimator is measured about the noise-free fit (its deterministic model-mismatch bias is
printed separately, as the error of the noise-free fit against the truth), and, for honesty,
also about the truth.

Run: python benchmarks/mc_efficiency.py [--n 200] [--sigma 0.5]   (a few minutes)
"""
from __future__ import annotations

import argparse
import dataclasses
import time

import numpy as np


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--n", type=int, default=200)
    ap.add_argument("--sigma", type=float, default=0.5)
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args()

    from kukaid import excite
    from kukaid.identify import fit_dynamic, preprocess
    from kukaid.identify.dynamic import _columns
    from kukaid.identify.stribeck_fit import prediction_and_jac
    from kukaid.sim import SimConfig, VirtualKRC4

    truth = dict(Fc=12.3, Fs=15.1, vs=0.055, delta=1.4, Fv=9.7, Izz=1.73, Mx=24.6)
    cfg = SimConfig().replace(noise_sigma=0.0, vibration=False, **truth)
    logs = [VirtualKRC4(cfg, seed=a.seed).run(excite.generate(k)) for k in ("friction", "inertia")]
    ref = fit_dynamic([preprocess(lg, 3) for lg in logs])
    p_ref = ref.params_
    # Jacobian over the fitted samples at the noise-free fit, natural parameters
    preps = [preprocess(lg, 3) for lg in logs]
    As, vs = [], []
    for pr in preps:
        names, A = _columns(pr, "stribeck", "cos", False, None, pr.dynamic)
        As.append(A)
        vs.append(pr.qd[pr.dynamic])
    A, v = np.vstack(As), np.concatenate(vs)
    p_nat = np.r_[[p_ref[k] for k in names], p_ref["Fs"] - p_ref["Fc"], p_ref["vs"], p_ref["delta"]]
    _, J = prediction_and_jac(A, v, p_nat)
    # to (..., Fs, vs, delta): Fs = Fc + dF -> dF = Fs - Fc
    allnames = [*names, "Fs", "vs", "delta"]
    T = np.eye(len(allnames))
    T[len(names), names.index("Fc")] = 1.0  # Fs row
    crb_nat = a.sigma ** 2 * np.linalg.inv(J.T @ J)
    crb = T @ crb_nat @ T.T
    crb_std = dict(zip(allnames, np.sqrt(np.diag(crb))))

    rng_master = np.random.SeedSequence(a.seed)
    est = {k: [] for k in ("Izz", "Mx", "Fc", "Fv")}
    t0 = time.perf_counter()
    for child in rng_master.spawn(a.n):
        rng = np.random.default_rng(child)
        noisy = [dataclasses.replace(lg, tau=lg.tau + a.sigma * rng.standard_normal(lg.tau.shape)) for lg in logs]
        f = fit_dynamic([preprocess(lg, 3) for lg in noisy])
        for k in est:
            est[k].append(f.params_[k])
    dt = time.perf_counter() - t0
    print(f"{a.n} noise realisations (sigma {a.sigma} N*m) on one noise-free run: {ref.n_samples} dynamic samples, "
          f"{dt:.0f} s")
    print(f"{'param':<6} {'truth':>9} {'noise-free fit':>15} {'bias':>9} {'mean':>10} {'RMSE':>10} {'RMSE/truth':>11} "
          f"{'CRB std':>10} {'RMSE/CRB':>9}")
    for k, xs in est.items():
        x = np.asarray(xs)
        rmse = float(np.sqrt(np.mean((x - p_ref[k]) ** 2)))
        rmse_t = float(np.sqrt(np.mean((x - truth[k]) ** 2)))
        print(f"{k:<6} {truth[k]:>9.5g} {p_ref[k]:>15.6g} {p_ref[k] - truth[k]:>+9.2g} {x.mean():>10.6g} "
              f"{rmse:>10.3g} {rmse_t:>11.3g} {crb_std[k]:>10.3g} {rmse / crb_std[k]:>9.2f}")
    print("RMSE about the noise-free fit (the estimator's random error); RMSE/truth adds the model-mismatch bias. "
          "Target: RMSE/CRB <= 1.3.")


if __name__ == "__main__":
    main()
