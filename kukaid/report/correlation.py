"""Page 5: parameter correlation and the torque residual's histogram, spectrum and autocorrelation."""
from __future__ import annotations

import math
import textwrap
from typing import Any

import numpy as np


from kukaid.report.data import (PARAM_ORDER, ReportData, _flat_params, _runs, dynamic_residual)
from kukaid.report.layout import _new_figure


def correlation_from_data(data: ReportData) -> tuple[list[str], np.ndarray] | None:
    """Correlation of the dynamic-model parameters from the Jacobian at the fitted parameters on the
    dynamic samples of the given friction, inertia and general logs (None if there are none)."""
    from kukaid.models.friction import friction_columns
    from kukaid.models.joint import rigid_columns
    from kukaid.identify.stribeck_fit import natural_uncertainty, prediction_and_jac, SeparableResult
    from kukaid.identify.uncertainty import covariance

    preps = [pr for _, pr in data.friction + data.inertia + data.general]
    par = data.params
    prov = par.get("provenance") or {}
    gravity = prov.get("gravity") or ("cos+sin" if "My" in par["inertial"] else "cos")
    offset = "offset" in par
    As, vs, ys = [], [], []
    names: list[str] = []
    for pr in preps:
        m = pr.dynamic
        if not m.any():
            continue
        names, R = rigid_columns(pr.q[m], pr.qdd[m], gravity, offset)
        As.append(np.column_stack([R, friction_columns("coulomb-viscous", pr.qd[m])[1]]))
        vs.append(pr.qd[m])
        ys.append(pr.tau[m])
    if not As:
        return None
    names = [*names, "Fc", "Fv"]
    A, v, y = np.vstack(As), np.concatenate(vs), np.concatenate(ys)
    if not (np.any(v > 0) and np.any(v < 0)) or y.size < len(names) + 5:
        return None
    flat = _flat_params(par)
    theta = np.array([flat.get(k, 0.0) for k in names])
    if par["friction"].get("model", "stribeck") == "stribeck":
        p = np.r_[theta, flat["Fs"] - flat["Fc"], flat["vs"], flat["delta"]]
        pred, J = prediction_and_jac(A, v, p)
        sr = SeparableResult([*names, "dF", "vs", "delta"], p, y - pred, J, 0.0, "", p, 0.0, 0, 0.0, {})
        _, u = natural_uncertainty(sr)
    else:
        u = covariance(y - A @ theta, A, names, theta)
    order = [k for k in PARAM_ORDER if k in u.names]
    idx = [list(u.names).index(k) for k in order]
    return order, u.corr[np.ix_(idx, idx)]


def residual_stats(data: ReportData, nseg: int = 256, max_lag_s: float = 2.0) -> dict[str, Any] | None:
    """Torque residual (measured - predicted) of the dynamic samples of the given logs: histogram
    data, Welch spectrum over dynamic runs, autocorrelation and the correlation factor."""
    items = data.friction + data.inertia + data.general
    if not items:
        return None
    res_all, segs_psd = [], []
    fs = None
    maxrun = 0
    runs_all = []
    for log, pr in items:
        r = dynamic_residual(data, log, pr)
        fs = fs or pr.fs / max(1, int(pr.settings.get("decimate", 1)))
        res_all.append(r[pr.dynamic])
        runs = _runs(pr.dynamic)
        runs_all.append((r, runs))
        maxrun = max([maxrun] + [b - a for a, b in runs])
    res = np.concatenate(res_all)
    if res.size < 10:
        return None
    n = int(min(nseg, maxrun))
    freqs = psd = None
    if n >= 32:
        win = np.hanning(n)
        scale = 1.0 / (fs * np.sum(win ** 2))
        for r, runs in runs_all:
            for a, b in runs:
                for s in range(a, b - n + 1, n // 2):
                    x = r[s:s + n] - np.mean(r[s:s + n])
                    X = np.fft.rfft(x * win)
                    segs_psd.append(scale * np.abs(X) ** 2)
        P = np.mean(segs_psd, axis=0)
        P[1:-1] *= 2.0
        freqs, psd = np.fft.rfftfreq(n, 1.0 / fs), P
    L = int(max(2, min(max_lag_s * fs, maxrun - 2)))
    num = np.zeros(L + 1)
    den = 0.0
    for r, runs in runs_all:
        for a, b in runs:
            x = r[a:b] - np.mean(res)
            den += float(x @ x)
            for k in range(0, min(L, x.size - 1) + 1):
                num[k] += float(x[: x.size - k] @ x[k:])
    rho = num / den if den > 0 else num
    cut = int(math.ceil(2 * fs / float((data.params.get("provenance") or {}).get("preprocess", {}).get("cutoff", 5.0))))
    factor = float(np.sqrt(max(1.0, 1.0 + 2.0 * rho[1:cut + 1].sum())))
    return {"residual": res, "freqs": freqs, "psd": psd, "lags": np.arange(L + 1) / fs, "rho": rho,
            "factor": factor, "fs": fs, "max_lag": cut}


def page_correlation(data: ReportData):
    """Correlation matrix (heat map with numbers) and the residual's histogram, spectrum, autocorrelation."""
    par = data.params
    met = par.get("metrics") or {}
    corr = met.get("correlation")
    names, C, csrc = None, None, ""
    if isinstance(corr, dict) and corr.get("names") and corr.get("matrix"):
        names, C = list(corr["names"]), np.asarray(corr["matrix"], dtype=float)
        csrc = "from the parameter file (joint fit)"
    else:
        got = correlation_from_data(data)
        if got is not None:
            names, C = got
            csrc = "computed by the report: Jacobian at the fitted parameters on the logs given"
    st = residual_stats(data)
    if C is None and st is None:
        return None
    tu = data.tu
    fig = _new_figure("Parameter correlation and torque residual", data)
    if C is not None:
        ax = fig.add_axes([0.16, 0.56, 0.62, 0.36])
        im = ax.imshow(C, vmin=-1, vmax=1, cmap="RdBu_r")
        ax.set_xticks(range(len(names)), names, fontsize=8)
        ax.set_yticks(range(len(names)), names, fontsize=8)
        for i in range(len(names)):
            for j in range(len(names)):
                ax.text(j, i, f"{C[i, j]:.2f}", ha="center", va="center", fontsize=7,
                        color="white" if abs(C[i, j]) > 0.6 else "black")
        cb = fig.colorbar(im, ax=ax, fraction=0.046, pad=0.04)
        cb.set_label("correlation coefficient", fontsize=8)
        ax.set_title(textwrap.fill(f"correlation matrix of the parameters ({csrc})", 90), fontsize=8.5)
    if st is not None:
        r = st["residual"]
        sd = float(np.std(r))
        a1 = fig.add_axes([0.11, 0.30, 0.36, 0.19])
        a1.hist(r, bins=60, density=True, color="C0", alpha=0.7, label="residual")
        xx = np.linspace(r.min(), r.max(), 200)
        if sd > 0:
            a1.plot(xx, np.exp(-0.5 * ((xx - r.mean()) / sd) ** 2) / (sd * math.sqrt(2 * math.pi)), "k-", lw=1,
                    label="normal, same mean/std")
        a1.set_xlabel(f"measured − predicted ({tu})")
        a1.set_ylabel(f"density (1/{tu})")
        a1.legend(fontsize=6.5)
        a1.set_title(f"histogram: {r.size} dynamic samples, RMS {np.sqrt(np.mean(r ** 2)):.3g} {tu}", fontsize=8)
        a1.grid(True, alpha=0.3)
        a2 = fig.add_axes([0.58, 0.30, 0.37, 0.19])
        if st["psd"] is not None:
            a2.semilogy(st["freqs"], st["psd"], "-", color="C2", lw=1)
            co = ((par.get("provenance") or {}).get("preprocess") or {}).get("cutoff")
            if co:
                a2.axvline(float(co), color="k", ls=":", lw=1, label=f"filter cut-off {float(co):.4g} Hz")
                a2.legend(fontsize=6.5)
            a2.set_xlabel("frequency (Hz)")
            a2.set_ylabel(f"PSD ({data.tu2}/Hz)")
            a2.set_title("residual spectrum (Welch, dynamic runs)", fontsize=8)
            a2.grid(True, alpha=0.3, which="both")
        else:
            a2.axis("off")
            a2.text(0.5, 0.5, "dynamic runs too short for a spectrum", ha="center", fontsize=8)
        a3 = fig.add_axes([0.11, 0.075, 0.84, 0.145])
        a3.plot(st["lags"], st["rho"], "-", color="C4", lw=1, label="autocorrelation ρk of the residual")
        a3.axhline(0, color="k", lw=0.5)
        a3.axvline(st["max_lag"] / st["fs"], color="0.5", ls=":", lw=1, label="lags summed for the factor")
        a3.set_xlabel("lag (s)")
        a3.set_ylabel("ρ (-)")
        a3.grid(True, alpha=0.3)
        a3.legend(fontsize=6.5, loc="upper right")
        fmet = met.get("residual_correlation_factor")
        title = (f"residuals are correlated in time, so the standard deviations are optimistic: factor "
                 f"sqrt(1 + 2 Σ ρk) = {st['factor']:.2f} here"
                 + (f", {float(fmet):.2f} in the fit's metrics" if isinstance(fmet, (int, float)) else ""))
        a3.set_title(textwrap.fill(title, 105), fontsize=8, loc="left")  # within the page
    return fig


# -- assembly ----------------------------------------------------------------------------------------
