"""The identification report: the paper's figures and tables of a fitted axis, and more.

Every ``page_*`` function returns one :class:`matplotlib.figure.Figure` (A4 portrait, built with
the object API: no pyplot state, no GUI backend); :func:`build_report` assembles the pages the
given data allow and :func:`write_report` writes them into one PDF atomically.

Pages
-----
1. parameters (always): value, standard deviation, relative std, std inflated by the residual
   correlation factor, simulator truth and error when a log carries it; Maxwell-slip elements;
   metrics beside the paper's reference values; the uncertainty caveat; provenance.
2. friction (``friction`` logs): Γf = (Γ+ - Γ-)/2 per speed (eqs. 2-4) and the fitted Stribeck
   curve (eq. 1), linear and log velocity axis, residuals.
3. torque prediction (one per ``inertia`` log, then one per general log): measured and predicted
   torque over time and the residual (eqs. 6-8).
4. pre-sliding (``presliding`` log): torque with gravity removed against displacement, and the
   fitted Maxwell-slip model (eqs. 9-10, 12) replayed on the same path.
5. correlation and residuals (when friction, inertia or general logs are given): correlation
   matrix of the parameters (heat map; from the parameter file, else computed from the logs at
   the fitted parameters), histogram, spectrum and autocorrelation of the torque residual.

Units: SI inside; figures show N·m, rad/s, rad (mrad for pre-sliding displacements).
"""
from __future__ import annotations

import math
import textwrap
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from kukaid.errors import FitError, KukaidError

#: The paper's figures (Yao et al. 2018, a real KR 6 R700 sixx, A3): references, not targets.
PAPER_FRICTION_MSE = 0.5249
PAPER_TORQUE_MSE = 14.59

A4 = (8.27, 11.69)
PARAM_ORDER = ("Fc", "Fs", "vs", "delta", "Fv", "Izz", "Mx", "My", "offset")
_UNITS_REV = {"Fc": "N·m", "Fs": "N·m", "vs": "rad/s", "delta": "-", "Fv": "N·m·s/rad", "Izz": "kg·m²",
              "Mx": "N·m", "My": "N·m", "offset": "N·m"}
_UNITS_PRIS = {"Fc": "N", "Fs": "N", "vs": "m/s", "delta": "-", "Fv": "N·s/m", "Izz": "kg", "Mx": "N",
               "My": "N", "offset": "N"}


class ReportError(KukaidError):
    """The report cannot be made from the given inputs (wrong axis, no usable samples, ...)."""


@dataclass
class ReportData:
    """Inputs of a report: the parameter file and the logs (prepared as the fit prepared them).

    params : validated parameter dictionary.   source : the parameter file's path (text).
    friction, inertia, general : lists of ``(log, prepared)``.   presliding : ``(log, prepared)``.
    truth : the simulator's truth (``log.attrs["truth"]``) when a log carries one, else None.
    """

    params: dict
    source: str = ""
    friction: list = field(default_factory=list)
    inertia: list = field(default_factory=list)
    general: list = field(default_factory=list)
    presliding: Any = None
    truth: dict | None = None
    truth_source: str = ""

    @property
    def prismatic(self) -> bool:
        return (self.params.get("provenance") or {}).get("joint") == "prismatic"

    @property
    def units(self) -> dict[str, str]:
        return _UNITS_PRIS if self.prismatic else _UNITS_REV

    @property
    def tu(self) -> str:
        """Torque unit (force for a prismatic axis)."""
        return "N" if self.prismatic else "N·m"

    @property
    def vu(self) -> str:
        return "m/s" if self.prismatic else "rad/s"


# -- loading -------------------------------------------------------------------------------------
def _prep_options(params: dict, fs: float) -> dict:
    s = (params.get("provenance") or {}).get("preprocess") or {}
    opts = {k: s[k] for k in ("cutoff", "order", "qd_thr", "reversal_window", "qdd_tol", "diff") if s.get(k) is not None}
    if s.get("decimate"):
        opts["decimate"] = int(s["decimate"])
    if s.get("edge") is not None and s.get("fs") and abs(float(s["fs"]) - fs) <= 0.01 * fs:
        opts["edge"] = int(s["edge"])
    if "qd_thr" not in opts:
        opts["qd_thr"] = float((params.get("mode_switch") or {}).get("qd_thr", 0.0017))
    return opts


def _load_one(x: Any, axis: int, params: dict) -> tuple[Any, Any]:
    from kukaid.identify import preprocess
    from kukaid.logs import read_log

    if hasattr(x, "tau") and hasattr(x, "time"):
        log = x
    else:
        p = Path(x)
        if not p.exists():
            raise ReportError(f"{p}: no such file")
        log = read_log(p)
    where = log.attrs.get("source_file", str(x) if not hasattr(x, "tau") else "axis log")
    if int(axis) not in tuple(int(a) for a in log.axes):
        raise ReportError(f"{where}: axis A{axis} is not in the log (axes: {list(log.axes)}); choose it with --axis")
    fs = 1.0 / float(np.median(np.diff(np.asarray(log.time, dtype=float)))) if log.time.size > 1 else 1.0
    try:
        pr = preprocess(log, axis=axis, **_prep_options(params, fs))
    except FitError as e:
        raise ReportError(str(e)) from None
    return log, pr


def load_report_data(params: dict | str | Path, friction: Sequence[Any] = (), inertia: Sequence[Any] = (),
                     presliding: Any = None, logs: Sequence[Any] = (), axis: int | None = None) -> ReportData:
    """Read the parameter file and the logs, and prepare the logs as the fit did.

    Parameters
    ----------
    params : parameter dictionary or path of a ``kukaid.params/1`` file.
    friction, inertia, logs : axis logs (paths or :class:`~kukaid.logs.axislog.AxisLog`).
    presliding : pre-sliding log, optional.
    axis : axis to report (default: the parameter file's ``axis``, else 3).

    Raises
    ------
    ParamFileError : broken parameter file.   LogFormatError, ReportError : missing or broken log,
    log without the axis, log too short for the filter.
    """
    from kukaid.params import load_params, validate_params

    if isinstance(params, dict):
        par, source = validate_params(params), "parameters"
    else:
        par, source = load_params(params), str(params)
    if axis is None:
        axis = int(par.get("axis") or 3)
    elif par.get("axis") is not None and int(par["axis"]) != int(axis):
        raise ReportError(f"{source}: the parameters are of axis A{par['axis']}, not A{axis}")
    data = ReportData(par, source)
    data.friction = [_load_one(x, axis, par) for x in friction]
    data.inertia = [_load_one(x, axis, par) for x in inertia]
    data.general = [_load_one(x, axis, par) for x in logs]
    if presliding is not None:
        data.presliding = _load_one(presliding, axis, par)
    every = data.friction + data.inertia + data.general + ([data.presliding] if data.presliding else [])
    for log, _ in every:
        t = log.attrs.get("truth")
        if isinstance(t, dict) and isinstance(t.get("friction"), dict) and int(t.get("axis", axis)) == int(axis):
            data.truth = t
            data.truth_source = str(log.attrs.get("source_file", "log"))
            break
    return data


# -- helpers -------------------------------------------------------------------------------------
def _flat_params(par: dict) -> dict[str, float]:
    out = {k: float(v) for k, v in par["friction"].items() if k != "model"}
    out.update({k: float(v) for k, v in par["inertial"].items()})
    if "offset" in par:
        out["offset"] = float(par["offset"])
    return {k: out[k] for k in PARAM_ORDER if k in out} | {k: v for k, v in out.items() if k not in PARAM_ORDER}


def _fmt(x: Any, sig: int = 5) -> str:
    if x is None:
        return "-"
    x = float(x)
    if not math.isfinite(x):
        return "-"
    return f"{x:.{sig}g}"


def _model(par: dict):
    from kukaid.params import model_from_params

    return model_from_params(par)


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    idx = np.flatnonzero(np.diff(np.r_[0, np.asarray(mask, dtype=int), 0]))
    return [(int(a), int(b)) for a, b in zip(idx[::2], idx[1::2])]


def _new_figure(title: str, data: ReportData):
    from matplotlib.figure import Figure

    fig = Figure(figsize=A4)
    fig.suptitle(title, fontsize=13, weight="bold", y=0.985)
    fig.text(0.5, 0.008, f"kukaid report · {Path(data.source).name} · axis A{data.params.get('axis', '?')}",
             ha="center", fontsize=7, color="0.4")
    return fig


def _add_table(ax, cells, cols, fontsize=8, col_widths=None, scale_y=1.25):
    ax.axis("off")
    tab = ax.table(cellText=cells, colLabels=cols, bbox=[0.0, 0.0, 1.0, 1.0], cellLoc="center",
                   colWidths=col_widths)
    tab.auto_set_font_size(False)
    tab.set_fontsize(fontsize)
    for (r, _), cell in tab.get_celld().items():
        cell.set_linewidth(0.4)
        if r == 0:
            cell.set_facecolor("#dde4ee")
            cell.set_text_props(weight="bold")
    return tab


def dynamic_residual(data: ReportData, pr: Any) -> np.ndarray:
    """Measured minus predicted torque (dynamic-mode model of the parameter file), every sample, N·m."""
    m = _model(data.params)
    return pr.tau - m.predict_dynamic(pr.q, pr.qd, pr.qdd)


# -- page 1: parameters ----------------------------------------------------------------------------
def page_parameters(data: ReportData):
    """Parameter table with uncertainties (and truth), metrics beside the paper's, caveat, provenance."""
    from kukaid import __version__

    par = data.params
    met = par.get("metrics") or {}
    unc = par.get("uncertainty") or {}
    prov = par.get("provenance") or {}
    units = data.units
    values = _flat_params(par)
    cf = met.get("residual_correlation_factor")
    cf = float(cf) if isinstance(cf, (int, float)) and math.isfinite(cf) else None
    cf_src = "of this fit (metrics)"
    if cf is None and (data.friction or data.inertia or data.general):
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
    fig.text(0.06, 0.955, f"friction model {model}, method {prov.get('method', '?')}, gravity "
             f"{prov.get('gravity', '?')}, joint {prov.get('joint', 'revolute')}; parameter file {data.source}",
             fontsize=7.5, wrap=True)
    # parameter table
    cols = ["parameter", "value", "unit", "std", "rel. std"]
    if cf is not None:
        cols.append(f"std × {cf:.2f}")
    if truth is not None:
        cols += ["truth", "error"]
    cells = []
    for k, v in values.items():
        s = unc.get(k)
        row = [k, _fmt(v, 6), units.get(k, ""), _fmt(s, 3),
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
    ax.set_title("identified parameters (std: from residual variance and Jacobian)", fontsize=9, loc="left")
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
    def add(label, key, unit, paper=None, fmt=lambda x: _fmt(x, 4)):
        v = met.get(key)
        if v is None:
            return
        mrow.append([label, fmt(v) if isinstance(v, (int, float)) else str(v), unit,
                     _fmt(paper, 4) if paper is not None else ""])
    tu2 = f"{data.tu}²".replace("N·m²", "N²m²")
    add("friction-fit MSE", "friction_fit_mse", tu2, PAPER_FRICTION_MSE)
    add("torque-prediction MSE", "torque_prediction_mse", tu2, PAPER_TORQUE_MSE)
    add("torque-prediction MSE, unfiltered torque", "torque_prediction_mse_raw", tu2)
    add("condition number (joint regressor)", "condition_number", "-")
    add("condition number (friction, staged)", "friction_condition_number", "-")
    add("condition number (inertia regressor)", "inertia_condition_number", "-")
    add("residual correlation factor", "residual_correlation_factor", "-")
    add("IPOPT status", "ipopt_status", "")
    add("dynamic-mode samples fitted", "n_dynamic_samples", "", fmt=lambda x: str(int(x)))
    add("friction pairs (staged)", "friction_pairs", "", fmt=lambda x: str(int(x)))
    add("Maxwell-slip fit RMS", "maxwell_slip_rms", data.tu)
    if mrow:
        h3 = 0.019 * (len(mrow) + 1)
        ax = fig.add_axes([0.04, y - h3, 0.92, h3])
        _add_table(ax, mrow, ["metric", "this fit", "unit", "paper (Yao et al. 2018, real KR C4)"], fontsize=7.5,
                   col_widths=[0.36, 0.2, 0.1, 0.34], scale_y=1.0)
        ax.set_title("metrics; the paper's values are a reference from real data, not targets", fontsize=9, loc="left")
        y = y - h3 - 0.03
    # caveat
    cav = ("Uncertainty caveat: the standard deviations are s²(JᵀJ)⁻¹ from the residual variance and the Jacobian, "
           "which assumes white, independent residuals. The residuals of a fit on low-pass-filtered signals are "
           "correlated in time, so these standard deviations are OPTIMISTIC (too small).")
    if cf is not None:
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
    for role, items in (("friction", data.friction), ("inertia", data.inertia), ("log", data.general),
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
        prov_lines.append(f"  effects in the parameter file (not drawn in the predictions): {', '.join(par['effects'])}")
    for ln in prov_lines:
        for sub in textwrap.wrap(ln, 130, subsequent_indent="      ") or [""]:
            if y < 0.025:
                break
            fig.text(0.05, y, sub, fontsize=6.8, family="monospace")
            y -= 0.0135
    return fig


# -- page 2: friction ------------------------------------------------------------------------------
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
    ax.set_title(f"residual of the friction fit: MSE on these points {mse:.4g} {tu}²"
                 + (f"; fit's friction_fit_mse {fm:.4g}" if isinstance(fm, (int, float)) else "")
                 + f"; paper {PAPER_FRICTION_MSE} (reference)", fontsize=8.5, loc="left")
    ax.legend(fontsize=7, loc="upper right")
    return fig


# -- page 3: torque prediction ---------------------------------------------------------------------
def page_prediction(data: ReportData, log: Any, pr: Any, role: str = "inertia"):
    """Measured vs predicted torque over time, the residual, and the motion (paper's torque figure)."""
    pred = _model(data.params).predict_dynamic(pr.q, pr.qd, pr.qdd)
    res = pr.tau - pred
    m = pr.dynamic
    mse = float(np.mean(res[m] ** 2)) if m.any() else float("nan")
    tu = data.tu
    t = pr.time - pr.time[0]
    title = ("Torque prediction on the inertia experiment (eqs. 6-8)" if role == "inertia"
             else "Torque prediction on a general log (validation)")
    fig = _new_figure(title, data)
    fig.text(0.06, 0.955, f"{pr.source}", fontsize=7.5)
    a1 = fig.add_axes([0.11, 0.62, 0.78, 0.30])
    a2 = fig.add_axes([0.11, 0.36, 0.78, 0.20], sharex=a1)
    a3 = fig.add_axes([0.11, 0.07, 0.78, 0.22], sharex=a1)
    pred_d = np.where(m, pred, np.nan)
    res_d = np.where(m, res, np.nan)
    a1.plot(t, pr.tau_raw, "-", color="0.75", lw=0.5, label="measured (raw)")
    a1.plot(t, pr.tau, "-", color="C0", lw=1.0, label="measured (filtered)")
    a1.plot(t, pred_d, "--", color="C3", lw=1.0, label="predicted Izz q̈ + gravity + F(q̇) (dynamic samples)")
    a1.set_ylabel(f"torque Γ ({tu})")
    a1.legend(fontsize=7, loc="upper right")
    a1.grid(True, alpha=0.3)
    a1.set_title(f"MSE on the {int(m.sum())} dynamic-mode samples: {mse:.4g} {tu}²; paper {PAPER_TORQUE_MSE} {tu}² "
                 "(real data, reference)", fontsize=8.5, loc="left")
    a2.plot(t, res_d, "-", color="C2", lw=0.8, label="measured − predicted")
    a2.axhline(0, color="k", lw=0.5)
    for a, b in _runs(~m):
        a2.axvspan(t[a], t[min(b, t.size - 1)], color="0.85", lw=0)
    a2.set_ylabel(f"residual ({tu})")
    a2.grid(True, alpha=0.3)
    if m.any():
        lim = 1.3 * float(np.max(np.abs(res[m]))) + 1e-9
        a2.set_ylim(-lim, lim)
    a2.legend(fontsize=7, loc="upper right", title="grey: not fitted (quasi-static / near reversal)",
              title_fontsize=6.5)
    a3.plot(t, pr.q, "-", color="C0", lw=1.0, label="position q")
    a3.set_ylabel("position q (m)" if data.prismatic else "position q (rad)")
    a3.set_xlabel("time (s)")
    a3.grid(True, alpha=0.3)
    b3 = a3.twinx()
    b3.plot(t, pr.qd, "-", color="C1", lw=0.8, label="velocity q̇")
    b3.set_ylabel(f"velocity q̇ ({data.vu})")
    h1, l1 = a3.get_legend_handles_labels()
    h2, l2 = b3.get_legend_handles_labels()
    a3.legend(h1 + h2, l1 + l2, fontsize=7, loc="upper right")
    return fig


# -- page 4: pre-sliding ---------------------------------------------------------------------------
def presliding_replay(data: ReportData) -> dict[str, np.ndarray | float]:
    """Measured torque (gravity removed) and the Maxwell-slip model on the same displacement path.

    The data are the longest quasi-static stretch of the pre-sliding log (as the fit used):
    ``z = q - q_stop``; the model starts from the stored element positions (relative to the
    stop, eq. 12); a constant (the unmodelled Γu) is the mean difference.
    Returns {"t", "z", "y", "model", "constant", "rms"}; "model" is None without Maxwell-slip.
    """
    from kukaid.models.friction import MaxwellSlip

    log, pr = data.presliding
    runs = _runs(pr.quasi_static)
    if not runs:
        raise ReportError(f"{pr.source}: pre-sliding page: no quasi-static samples (|qd| < qd_thr)")
    a, b = max(runs, key=lambda r: r[1] - r[0])
    if b - a < 5:
        raise ReportError(f"{pr.source}: pre-sliding page: the longest quasi-static stretch has {b - a} samples")
    z = pr.q[a:b] - pr.q[a]
    y = pr.tau[a:b] - _model(data.params).rigid.gravity(pr.q[a:b])
    ms = data.params.get("maxwell_slip")
    out: dict[str, Any] = {"t": pr.time[a:b] - pr.time[a], "z": z, "model": None}
    if ms:
        F, _ = MaxwellSlip(ms["k"], ms["W"]).simulate(z, np.asarray(ms.get("zeta0", [0.0] * len(ms["k"])), float))
        c = float(np.mean(y - F))
        out.update(model=F, constant=c, y=y - c, rms=float(np.sqrt(np.mean((y - c - F) ** 2))))
    else:
        c = float(np.mean(y))
        out.update(constant=c, y=y - c, rms=float("nan"))
    return out


def page_presliding(data: ReportData):
    """Hysteresis loops: torque (gravity removed) vs displacement, with the Maxwell-slip model replayed."""
    r = presliding_replay(data)
    tu = data.tu
    zs, zu = (1e3, "mm") if data.prismatic else (1e3, "mrad")
    fig = _new_figure("Pre-sliding: hysteresis and the Maxwell-slip model (eqs. 9-10, 12)", data)
    fig.text(0.06, 0.955, data.presliding[1].source, fontsize=7.5)
    a1 = fig.add_axes([0.12, 0.45, 0.76, 0.47])
    a2 = fig.add_axes([0.12, 0.07, 0.76, 0.30])
    a1.plot(zs * r["z"], r["y"], "-", color="C0", lw=0.8, label="measured Γ − Mx cos q − c")
    if r["model"] is not None:
        a1.plot(zs * r["z"], r["model"], "-", color="C3", lw=0.9, alpha=0.85,
                label=f"Maxwell-slip model, same path ({len(data.params['maxwell_slip']['k'])} elements)")
    a1.set_xlabel(f"displacement z = q − q_stop ({zu})")
    a1.set_ylabel(f"torque ({tu})")
    a1.grid(True, alpha=0.3)
    a1.legend(fontsize=7, loc="upper left")
    msg = (f"quasi-static stretch, {r['z'].size} samples; c = {r['constant']:.4g} {tu} (unmodelled Γu); "
           + (f"model RMS error {r['rms']:.3g} {tu}" if r["model"] is not None
              else "no Maxwell-slip elements in the parameter file"))
    a1.set_title(msg, fontsize=8.5, loc="left")
    a2.plot(r["t"], r["y"], "-", color="C0", lw=0.8, label="measured")
    if r["model"] is not None:
        a2.plot(r["t"], r["model"], "-", color="C3", lw=0.8, alpha=0.85, label="Maxwell-slip model")
    a2.set_xlabel("time since the stop (s)")
    a2.set_ylabel(f"torque ({tu})")
    a2.grid(True, alpha=0.3)
    b2 = a2.twinx()
    b2.plot(r["t"], zs * r["z"], "-", color="0.6", lw=0.6, label="displacement z")
    b2.set_ylabel(f"z ({zu})", color="0.4")
    h1, l1 = a2.get_legend_handles_labels()
    h2, l2 = b2.get_legend_handles_labels()
    a2.legend(h1 + h2, l1 + l2, fontsize=7, loc="upper right")
    return fig


# -- page 5: correlation and residuals -------------------------------------------------------------
def correlation_from_data(data: ReportData) -> tuple[list[str], np.ndarray] | None:
    """Correlation of the dynamic-model parameters from the Jacobian at the fitted parameters on the
    dynamic samples of the given friction, inertia and general logs (None if there are none)."""
    from kukaid.identify.least_squares import rigid_columns
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
        As.append(np.column_stack([R, np.sign(pr.qd[m]), pr.qd[m]]))
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
    for _, pr in items:
        r = dynamic_residual(data, pr)
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
        ax.set_title(f"correlation matrix of the parameters ({csrc})", fontsize=8.5)
    if st is not None:
        r = st["residual"]
        sd = float(np.std(r))
        a1 = fig.add_axes([0.09, 0.30, 0.38, 0.19])
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
                a2.axvline(float(co), color="k", ls=":", lw=1, label=f"filter cut-off {float(co):g} Hz")
                a2.legend(fontsize=6.5)
            a2.set_xlabel("frequency (Hz)")
            a2.set_ylabel(f"PSD ({tu}²/Hz)")
            a2.set_title("residual spectrum (Welch, dynamic runs)", fontsize=8)
            a2.grid(True, alpha=0.3, which="both")
        else:
            a2.axis("off")
            a2.text(0.5, 0.5, "dynamic runs too short for a spectrum", ha="center", fontsize=8)
        a3 = fig.add_axes([0.09, 0.06, 0.86, 0.17])
        a3.plot(st["lags"], st["rho"], "-", color="C4", lw=1, label="autocorrelation ρk of the residual")
        a3.axhline(0, color="k", lw=0.5)
        a3.axvline(st["max_lag"] / st["fs"], color="0.5", ls=":", lw=1, label="lags summed for the factor")
        a3.set_xlabel("lag (s)")
        a3.set_ylabel("ρ (-)")
        a3.grid(True, alpha=0.3)
        a3.legend(fontsize=6.5, loc="upper right")
        fmet = met.get("residual_correlation_factor")
        a3.set_title(f"residuals are correlated in time, so the standard deviations are optimistic: factor "
                     f"sqrt(1 + 2 Σ ρk) = {st['factor']:.2f} here"
                     + (f", {float(fmet):.2f} in the fit's metrics" if isinstance(fmet, (int, float)) else ""),
                     fontsize=8, loc="left")
    return fig


# -- assembly ----------------------------------------------------------------------------------------
def build_report(data: ReportData) -> list:
    """All pages the data allow, in order: parameters, friction, predictions, pre-sliding, correlation."""
    figs = [page_parameters(data)]
    if data.friction:
        figs.append(page_friction(data))
    for log, pr in data.inertia:
        figs.append(page_prediction(data, log, pr, "inertia"))
    for log, pr in data.general:
        figs.append(page_prediction(data, log, pr, "general"))
    if data.presliding is not None:
        figs.append(page_presliding(data))
    if data.friction or data.inertia or data.general:
        fc = page_correlation(data)
        if fc is not None:
            figs.append(fc)
    return figs


def write_report(path: str | Path, figures: Sequence[Any], title: str = "kukaid identification report") -> int:
    """Write the figures as pages of one PDF, atomically (no file is left on failure); returns pages."""
    from matplotlib.backends.backend_pdf import PdfPages

    from kukaid import __version__
    from kukaid.atomic import atomic_path

    if not figures:
        raise ReportError("nothing to write: no pages")
    with atomic_path(path) as tmp:
        with PdfPages(tmp, metadata={"Title": title, "Creator": f"kukaid {__version__}"}) as pdf:
            for fig in figures:
                pdf.savefig(fig)
    return len(figures)


def make_report(params: dict | str | Path, output: str | Path, friction: Sequence[Any] = (),
                inertia: Sequence[Any] = (), presliding: Any = None, logs: Sequence[Any] = (),
                axis: int | None = None) -> int:
    """Load, build and write the report (see :func:`load_report_data`); returns the page count.

    Every input is read and every page drawn before the output file is created, so bad input
    raises a :class:`~kukaid.errors.KukaidError` and leaves no PDF.
    """
    data = load_report_data(params, friction, inertia, presliding, logs, axis)
    return write_report(output, build_report(data))
