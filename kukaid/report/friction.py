"""Page 2: the Stribeck curve (eq. 1) over the measured friction per speed (eqs. 2-4)."""
from __future__ import annotations


import numpy as np

from kukaid.errors import FitError

from kukaid.report.data import (PAPER_FRICTION_MSE, ReportData, ReportError, _fmt, _model)
from kukaid.report.layout import _new_figure


def _speed_groups(v: np.ndarray, tol: float = 0.05) -> list[np.ndarray]:
    order = np.argsort(v)
    vs = v[order]
    cuts = np.flatnonzero(np.diff(vs) > tol * np.maximum(vs[1:], 1e-12)) + 1
    return [order[s] for s in np.split(np.arange(v.size), cuts)]


def friction_points(data: ReportData) -> tuple[np.ndarray, np.ndarray, str]:
    """Friction samples of the friction logs: (speed, friction, how).

    Staged extraction Γf = (Γ+ - Γ-)/2 at the same positions (eqs. 2-4) when the logs hold paired
    constant-velocity moves; else ``(Γ - Izz qdd - gravity) sign(qd)`` on the dynamic samples.
    """
    from kukaid.identify.stribeck_fit import extract_friction

    preps = [pr for _, pr in data.friction]
    try:
        pts = extract_friction(preps)
        return pts.v, pts.gamma_f, "staged: Γf = (Γ+ − Γ−)/2 at the same positions (eqs. 2-4)"
    except FitError:
        rigid = _model(data.params).rigid
        v, g = [], []
        for pr in preps:
            m = pr.dynamic
            f = pr.tau[m] - rigid.torque(pr.q[m], pr.qdd[m])
            v.append(np.abs(pr.qd[m]))
            g.append(f * np.sign(pr.qd[m]))
        v, g = np.concatenate(v), np.concatenate(g)
        if v.size == 0:
            raise ReportError("friction logs: no dynamic-mode samples to draw the friction from")
        return v, g, "no paired sweeps: (Γ − Izz q̈ − gravity)·sign(q̇) on the dynamic samples"


def page_friction(data: ReportData):
    """Extracted friction per speed and the fitted Stribeck curve (linear and log speed), residuals."""
    v, g, how = friction_points(data)
    fr = _model(data.params).friction
    tfr = None
    if data.truth is not None:
        from kukaid.models.friction import friction_from_dict

        try:
            tfr = friction_from_dict(data.truth["friction"])
        except (KeyError, ValueError, TypeError):
            tfr = None
    ok = v > 0
    v, g = v[ok], g[ok]
    groups = _speed_groups(v)
    gv = np.array([np.mean(v[i]) for i in groups])
    gm = np.array([np.mean(g[i]) for i in groups])
    gs = np.array([np.std(g[i]) for i in groups])
    res = g - fr(v)
    mse = float(np.mean(res ** 2))
    fname = ("the fitted Stribeck curve (eq. 1)" if data.params["friction"].get("model", "stribeck") == "stribeck"
             else "the fitted Coulomb + viscous line")
    fig = _new_figure(f"Friction: extracted Γf and {fname}", data)
    axes = [fig.add_axes([0.11, 0.68, 0.84, 0.25]), fig.add_axes([0.11, 0.37, 0.84, 0.25]),
            fig.add_axes([0.11, 0.07, 0.84, 0.22])]
    vmax = float(v.max()) * 1.08
    vlin = np.linspace(0.0, vmax, 600)[1:]
    vmin_log = max(float(v.min()) / 3.0, 1e-5)
    vlog = np.geomspace(vmin_log, vmax, 600)
    label_fit = (f"fitted {data.params['friction'].get('model', 'stribeck')}: "
                 + ", ".join(f"{k} {_fmt(x, 4)}" for k, x in data.params["friction"].items() if k != "model"))
    tu, vu = data.tu, data.vu
    for ax, vv, logx in ((axes[0], vlin, False), (axes[1], vlog, True)):
        ax.plot(v, g, ".", ms=1.5, color="0.65", alpha=0.5, label="extracted samples", rasterized=True)
        ax.errorbar(gv, gm, yerr=gs, fmt="o", ms=4, color="C0", capsize=2, label="mean ± std per speed")
        ax.plot(vv, fr(vv), "-", color="C3", lw=1.6, label=label_fit)
        if tfr is not None:
            ax.plot(vv, tfr(vv), "--", color="k", lw=1.0, label="simulator truth")
        ax.set_ylabel(f"friction torque Γf ({tu})")
        ax.grid(True, alpha=0.3)
        if logx:
            ax.set_xscale("log")
            ax.set_xlim(vmin_log, vmax)
            vs_ = float(getattr(fr, "vs", 0.0))
            low = vlog[vlog <= (max(5 * vs_, 3 * vmin_log) if vs_ > 0 else vmax)]
            lo, hi = float(fr(low).min()), float(fr(low).max())
            sel = v <= low.max()
            if sel.any():
                lo = min(lo, float(np.percentile(g[sel], 1)))
                hi = max(hi, float(np.percentile(g[sel], 99)))
            pad = (0.6 if vs_ > 0 else 0.08) * (hi - lo) + 0.3
            ax.set_ylim(lo - pad, hi + pad)
            ax.set_title("log speed axis, zoomed on the low-speed Stribeck region" if vs_ > 0 else
                         "log speed axis (no Stribeck term in this model)", fontsize=9, loc="left")
        else:
            ax.set_xlim(0, vmax)
            ax.set_title(how, fontsize=9, loc="left")
        ax.set_xlabel(f"speed |q̇| ({vu})")
        ax.legend(fontsize=7, loc="lower right" if not logx else "upper left")
    ax = axes[2]
    ax.plot(v, res, ".", ms=1.5, color="0.6", alpha=0.5, rasterized=True, label="samples")
    gr = np.array([np.mean(res[i]) for i in groups])
    ax.plot(gv, gr, "o", ms=4, color="C0", label="mean per speed")
    ax.axhline(0, color="k", lw=0.6)
    ax.set_xscale("log")
    ax.set_xlabel(f"speed |q̇| ({vu})")
    ax.set_ylabel(f"Γf − F(q̇) ({tu})")
    ax.grid(True, alpha=0.3)
    fm = (data.params.get("metrics") or {}).get("friction_fit_mse")
    ax.set_title(f"residual of the friction fit: MSE on these points {mse:.4g} {data.tu2}"
                 + (f"; fit's friction_fit_mse {fm:.4g}" if isinstance(fm, (int, float)) else "")
                 + ("" if data.prismatic else f"; paper {PAPER_FRICTION_MSE} (reference)"), fontsize=8.5, loc="left")
    ax.legend(fontsize=7, loc="upper right")
    return fig


# -- page 3: torque prediction ---------------------------------------------------------------------
