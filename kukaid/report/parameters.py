"""Page 1: parameters with standard deviations, simulator truth, Maxwell-slip elements, metrics, provenance."""
from __future__ import annotations

import math
import textwrap



from kukaid.report.data import (PAPER_FRICTION_MSE, PAPER_TORQUE_MSE, ReportData, _flat_params, _fmt)
from kukaid.report.correlation import residual_stats
from kukaid.report.layout import _add_table, _new_figure, _subtitle


def page_parameters(data: ReportData):
    """Parameter table with uncertainties (and truth), metrics beside the paper's, caveat, provenance."""
    from kukaid import __version__
    from kukaid.identify.fit import solver_text

    par = data.params
    met = par.get("metrics") or {}
    refined = isinstance(met.get("original_fit"), dict)  # diagnose -o: the fit's figures are of the model without its effects
    unc = par.get("uncertainty") or {}
    prov = par.get("provenance") or {}
    units = data.units
    values = _flat_params(par)
    cf = met.get("residual_correlation_factor")
    cf = float(cf) if isinstance(cf, (int, float)) and math.isfinite(cf) else None
    cf_src = "of this fit (metrics)"
    if cf is None and not refined and (data.friction or data.inertia or data.general):  # HAC std need none
        st = residual_stats(data)
        if st is not None:
            cf, cf_src = float(st["factor"]), "computed by the report from the logs given"
    truth = None
    if data.truth is not None:
        truth = {**{k: v for k, v in (data.truth.get("friction") or {}).items() if k != "model"},
                 **(data.truth.get("inertial") or {})}
        if "offset" in data.truth:
            truth["offset"] = data.truth["offset"]
    fig = _new_figure(f"kukaid identification report: axis A{par.get('axis', '?')}", data)
    model = par["friction"].get("model", "stribeck")
    subtitle = (f"friction model {model}, method {prov.get('method', '?')}, gravity {prov.get('gravity', '?')}, "
                f"joint {prov.get('joint', 'revolute')}; parameter file {data.source}")
    _subtitle(fig, subtitle)
    # parameter table
    cols = ["parameter", "value", "unit", "std", "rel. std"]
    if cf is not None:
        cols.append(f"std × {cf:.2f}")
    if truth is not None:
        cols += ["truth", "error"]
    cells = []
    for k, v in values.items():
        s = unc.get(k)
        row = ["M (Izz: mass)" if k == "Izz" and data.prismatic else k, _fmt(v, 6), units.get(k, ""), _fmt(s, 3),
               f"{100 * s / abs(v):.3g} %" if s is not None and v else "-"]
        if cf is not None:
            row.append(_fmt(s * cf, 3) if s is not None else "-")
        if truth is not None:
            t = truth.get(k)
            if t is None:
                row += ["-", "-"]
            else:
                t = float(t)
                err = f"{100 * (v - t) / abs(t):+.2f} %" if t != 0 else f"{v - t:+.3g}"
                row += [_fmt(t, 6), err]
        cells.append(row)
    n_rows = len(cells) + 1
    h = 0.021 * n_rows
    top = 0.925
    ax = fig.add_axes([0.04, top - h, 0.92, h])
    _add_table(ax, cells, cols, fontsize=8, scale_y=1.0)
    ax.set_title("identified parameters (std: " + ("HAC, of diagnose's refit with the effects" if refined else
                                                   "from residual variance and Jacobian") + ")", fontsize=9, loc="left")
    y = top - h - 0.035
    # Maxwell-slip
    ms = par.get("maxwell_slip")
    if ms:
        mcols = ["element", "k (N·m/rad)", "W (N·m)", "W/k (µrad)", "ζ0 (µrad)"]
        tms = (data.truth or {}).get("maxwell_slip") if data.truth else None
        mcells = [[str(i + 1), _fmt(k, 6), _fmt(W, 4), _fmt(1e6 * W / k, 4), _fmt(1e6 * z, 4)]
                  for i, (k, W, z) in enumerate(zip(ms["k"], ms["W"], ms.get("zeta0", [0.0] * len(ms["k"]))))]
        sw = sum(ms["W"])
        mcells.append(["sum W", "", _fmt(sw, 4), "", ""])
        if tms:
            mcols += ["truth k", "truth W"]
            ordk = sorted(zip(tms["k"], tms["W"]), key=lambda kw: kw[1] / kw[0])
            for i, row in enumerate(mcells[:-1]):
                row += [_fmt(ordk[i][0], 6), _fmt(ordk[i][1], 4)] if i < len(ordk) else ["-", "-"]
            tsw = sum(tms["W"])
            mcells[-1] += ["", f"{_fmt(tsw, 4)} ({100 * (sw - tsw) / tsw:+.1f} %)" if tsw else _fmt(tsw, 4)]
        h2 = 0.019 * (len(mcells) + 1)
        ax = fig.add_axes([0.04, y - h2, 0.92, h2])
        _add_table(ax, mcells, mcols, fontsize=7.5, scale_y=1.0)
        ax.set_title("Maxwell-slip elements (eqs. 9-10), sorted as fitted"
                     + ("; truth sorted by W/k" if tms else ""), fontsize=9, loc="left")
        y = y - h2 - 0.035
    # metrics beside the paper
    mrow = []
    fm = met["original_fit"] if refined else met
    of = "original fit (no effects): " if refined else ""

    def add(label, key, unit, paper=None, fmt=lambda x: _fmt(x, 4) if isinstance(x, (int, float)) else str(x),
            src=fm):
        v = src.get(key)
        if v is None:
            return
        mrow.append([(of if src is fm else "") + label, fmt(v), unit, _fmt(paper, 4) if paper is not None else ""])
    tu2 = data.tu2
    revolute = not data.prismatic  # the paper's figures are of a revolute axis, in N·m: no reference for a force
    if refined:
        add("torque RMSE, diagnose's refit with the effects", "torque_rmse", data.tu, src=met)
        add("the same / noise floor", "residual_over_noise", "-", src=met)
    add("friction-fit MSE", "friction_fit_mse", tu2, PAPER_FRICTION_MSE if revolute else None)
    add("torque-prediction MSE", "torque_prediction_mse", tu2, PAPER_TORQUE_MSE if revolute else None)
    add("torque-prediction MSE, unfiltered torque", "torque_prediction_mse_raw", tu2)
    add("condition number (joint regressor)", "condition_number", "-")
    add("condition number (friction, staged)", "friction_condition_number", "-")
    add("condition number (inertia regressor)", "inertia_condition_number", "-")
    add("residual correlation factor", "residual_correlation_factor", "-")
    add("solver", "ipopt_status", "", fmt=solver_text)
    add("dynamic-mode samples fitted", "n_dynamic_samples", "", fmt=lambda x: str(int(x)))
    add("friction pairs (staged)", "friction_pairs", "", fmt=lambda x: str(int(x)))
    add("Maxwell-slip fit RMS", "maxwell_slip_rms", data.tu, src=met)
    if mrow:
        h3 = 0.019 * (len(mrow) + 1)
        ax = fig.add_axes([0.04, y - h3, 0.92, h3])
        if revolute:
            _add_table(ax, mrow, ["metric", "value", "unit", "paper (Yao et al. 2018, real KR C4)"], fontsize=7.5,
                       col_widths=[0.36, 0.2, 0.1, 0.34], scale_y=1.0)
            ax.set_title("metrics; the paper's values are a reference from real data, not targets", fontsize=9,
                         loc="left")
        else:  # the paper's figures are torques of a revolute axis: nothing to set beside a force
            _add_table(ax, [r[:3] for r in mrow], ["metric", "value", "unit"], fontsize=7.5,
                       col_widths=[0.5, 0.3, 0.2], scale_y=1.0)
            ax.set_title("metrics", fontsize=9, loc="left")
        y = y - h3 - 0.03
    # caveat
    cav = ("Uncertainty caveat: the standard deviations are s²(JᵀJ)⁻¹ from the residual variance and the Jacobian, "
           "which assumes white, independent residuals. The residuals of a fit on low-pass-filtered signals are "
           "correlated in time, so these standard deviations are OPTIMISTIC (too small).")
    if refined:
        cav = f"Uncertainty: {met.get('std_note')}; the original fit's figures are of the model without the effects."
    elif cf is not None:
        cav += (f" The residual correlation factor sqrt(1 + 2 Σ ρk) ({cf_src}) is {cf:.2f}: multiply the standard "
                f"deviations by about {cf:.2f} for a more realistic figure (column 'std × {cf:.2f}').")
    else:
        cav += " (No residual correlation factor in the parameter file's metrics.)"
    lines = textwrap.wrap(cav, 118)
    for ln in lines:
        fig.text(0.05, y, ln, fontsize=7.5, color="#8a1c1c")
        y -= 0.0155
    y -= 0.01
    # provenance
    logs = prov.get("logs") or {}
    pp = prov.get("preprocess") or {}
    prov_lines = ["Provenance:"]
    for role in ("friction", "inertia", "general"):
        for p in logs.get(role) or []:
            prov_lines.append(f"  fitted {role} log: {p}")
    if logs.get("presliding"):
        prov_lines.append(f"  fitted presliding log: {logs['presliding']}")
    if pp:
        prov_lines.append(f"  pre-processing: Butterworth order {pp.get('order')} at {_fmt(pp.get('cutoff'), 3)} Hz "
                          f"zero-phase, fs {_fmt(pp.get('fs'), 4)} Hz, qd_thr {_fmt(pp.get('qd_thr'), 3)} {data.vu}, "
                          f"reversal window {_fmt(pp.get('reversal_window'), 3)} s, {pp.get('diff', '?')} differences")
    seen = set()
    for role, items in (("friction", data.friction), ("inertia", data.inertia), ("general", data.general),
                        ("presliding", [data.presliding] if data.presliding else [])):
        for log, pr in items:
            a = log.attrs
            key = (role, pr.source)
            if key in seen:
                continue
            seen.add(key)
            bits = [f"{role} log in this report: {pr.source}"]
            if a.get("seed") is not None:
                bits.append(f"seed {a['seed']}")
            if a.get("source"):
                bits.append(f"source {a['source']}")
            if a.get("kukaid_version"):
                bits.append(f"captured by kukaid {a['kukaid_version']}")
            prov_lines.append("  " + ", ".join(bits))
    prov_lines.append(f"  fitted by kukaid {prov.get('kukaid_version', '?')}; report by kukaid {__version__}")
    if data.truth is not None:
        prov_lines.append(f"  truth: simulator truth stored in {data.truth_source} (attrs['truth'])")
    if par.get("effects"):
        prov_lines.append(f"  effects in the parameter file (in the predictions): {', '.join(par['effects'])}")
    for ln in prov_lines:
        for sub in textwrap.wrap(ln, 130, subsequent_indent="      ") or [""]:
            if y < 0.035:  # above the footer
                break
            fig.text(0.05, y, sub, fontsize=6.8, family="monospace")
            y -= 0.0135
    return fig


# -- page 2: friction ------------------------------------------------------------------------------
