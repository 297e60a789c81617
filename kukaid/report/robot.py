"""The report of a whole-robot fit (``kukaid.robot_params/1``): base parameters with σ, friction,
condition number and the physical-consistency check per link; with logs, the predicted against
the measured torque of every axis.

Pages: 1. base parameters (estimate, least squares, σ, σ times the residual correlation factor cf,
and σ × cf over |estimate|, fit's sigma %) and metrics; 2. friction, offset and spring per joint (± σ × cf),
consistency per link; 3.. one page per log given: measured and predicted torque of each axis over
time, with the relative error.
"""
from __future__ import annotations

import math
import textwrap
from pathlib import Path
from typing import Any, Callable, Sequence

from kukaid.report.layout import _add_table, _page, write_report


def _figure(title: str, source: str):
    return _page(title, f"kukaid robot report · {Path(source).name}")


def _g(v: Any, digits: int = 4) -> str:
    return "-" if v is None else f"{v:.{digits}g}"


def _pct(x: float) -> str:
    """A relative figure in %, two significant digits, never in exponent form (560 %, not 5.6e+02 %)."""
    return f"{x:.2g} %" if x < 99.5 else f"{x:.0f} %"


def page_base_parameters(params: dict, source: str):
    """Base-parameter table and the fit's metrics, the low-pass cut-off and how it was chosen."""
    from kukaid.identify.robot_fit import cutoff_line, relative_sigma

    bp, mt = params["base_parameters"], params.get("metrics") or {}
    cf = mt.get("residual_correlation_factor") or 1.0
    fig = _figure(f"Robot fit: base parameters ({params['robot'].get('name', '')})", source)
    cons = "yes" if mt.get("physically_consistent") else "no"
    sub = (f"URDF {params['robot']['urdf']}; {len(bp['values'])} base parameters; condition number "
           f"{_g(mt.get('condition_number'))}; physically consistent: {cons}; at a bound: "
           f"{', '.join(mt.get('at_bound') or []) or 'none'}; {mt.get('samples', '?')} samples fitted; "
           + cutoff_line((mt.get("choices") or {}).get("cutoff")  # a file without the choice: settings.cutoff
                         or {"chosen": params["settings"].get("cutoff"), "how": "settings.cutoff"}))
    # wrapped within the page, from below the title down (not up into it)
    fig.text(0.05, 0.963, textwrap.fill(sub, 130), fontsize=7, va="top")
    cells = []
    sig = bp.get("sigma") or [None] * len(bp["values"])
    rel = relative_sigma(params)  # as fit prints its sigma %
    for name, v, ls, s, r in zip(bp["names"], bp["values"], bp.get("least_squares", bp["values"]), sig, rel):
        short = name if len(name) <= 70 else name[:67] + "..."
        cells.append([short, _g(v), _g(ls), _g(s, 3), _g(None if s is None else s * cf, 3),
                      _pct(100 * r) if math.isfinite(r) else "-"])
    ax = fig.add_axes([0.03, 0.06, 0.94, 0.85])  # below the subtitle's four lines
    _add_table(ax, cells, ["base parameter (kg, kg·m, kg·m²)", "estimate", "least sq.", "σ", f"σ × {cf:.2f}",
                           "σ × cf / |est.|"], fontsize=5.5, col_widths=[0.53, 0.09, 0.09, 0.08, 0.09, 0.10])
    return fig


def page_friction_consistency(params: dict, source: str):
    """Friction/offset/spring per joint and the consistency check per link."""
    from kukaid.identify.robot_fit import table_number  # a parameter on its bound is 0, as `show` prints it

    fr, mt = params["friction"], params.get("metrics") or {}
    # the least-squares σ assume white residuals; page 1's base parameters are given times cf, and so are these
    cf = float(mt.get("residual_correlation_factor") or 1.0)
    fig = _figure("Robot fit: friction per joint, physical consistency per link", source)
    joints: dict[str, dict[str, str]] = {}
    for k, v in fr["values"].items():
        j, p = k.split(".", 1)
        if j.startswith("M"):   # motor k's rotor: a row under its axis (a column each overflowed the cells)
            j, p = f"A{j[1:]}", f"{p} (motor)"
        s = (fr.get("sigma") or {}).get(k)
        joints.setdefault(j, {})[p] = table_number(v) + (f"\n± {s * cf:.2g}" if s is not None else "")
    names = sorted({p for d in joints.values() for p in d})
    ax = fig.add_axes([0.05, 0.55, 0.9, 0.38])  # a row per parameter: a column each would overflow the cells
    first = 0.2   # the parameter's name
    _add_table(ax, [[p] + [d.get(p, "-") for d in joints.values()] for p in names], ["parameter"] + list(joints),
               fontsize=7 if len(joints) <= 6 else 6, col_widths=[first] + [(1 - first) / len(joints)] * len(joints))
    ax.set_title(f"friction model {fr['model']} (N·m, N·m·s/rad, N·m/rad; ± least-squares σ × the residual "
                 f"correlation factor {cf:.2f}, as page 1)", fontsize=8)
    chk = mt.get("consistency") or []
    links = params["robot"].get("links") or [f"link {i + 1}" for i in range(len(chk))]
    ax2 = fig.add_axes([0.05, 0.1, 0.9, 0.38])
    _add_table(ax2, [[ln, _g(c["mass"]), _g(c["triangle_margin"], 3), _g(c["pseudo_inertia_min_eig"], 3),
                      "yes" if c["ok"] else "NO"] for ln, c in zip(links, chk)],
               ["link", "mass (kg)", "triangle margin (kg·m²)", "min eig. pseudo-inertia", "consistent"], fontsize=7)
    ax2.set_title("physical consistency of the estimate (mass > 0, triangle inequalities at the centre of mass)",
                  fontsize=8)
    eff = params.get("effects") or {}
    if eff:   # named by kukaid diagnose: predicted with
        from kukaid.models.robot_effects import describe

        fig.text(0.05, 0.52, textwrap.fill("effects named by kukaid diagnose, predicted with: "
                                           + "; ".join(describe(k, e) for k, e in eff.items()), 130),
                 fontsize=7, va="top")
    return fig


def page_prediction(model: Any, log: Any, source: str):
    """Measured and predicted torque of every axis on one log (``model.predict``: a
    :class:`~kukaid.identify.fitted.FittedModel` of the robot file)."""
    pairs = model.predict(log)
    fig = _figure(f"Torque prediction: {Path(str(log.attrs.get('source_file', 'log'))).name}", source)
    n = len(pairs)
    for i, (a, (t, th)) in enumerate(pairs.items()):
        ax = fig.add_subplot(n, 1, i + 1)
        edge = (log.n_samples - t.size) // 2  # the predictor leaves out as many samples at either end
        x = log.time[edge:edge + t.size] - log.time[0]
        ax.plot(x, t, lw=0.6, label="measured")
        ax.plot(x, th, lw=0.6, label="predicted")
        rel = float(((t - th) ** 2).sum() ** 0.5 / max((t ** 2).sum() ** 0.5, 1e-12))
        ax.set_ylabel(f"A{a} (N·m)", fontsize=7)
        ax.tick_params(labelsize=6)
        ax.set_title(f"rel. error {100 * rel:.1f} %", loc="right", fontsize=7, pad=2)  # above the curves
        if i == 0:
            ax.legend(fontsize=6, loc="upper left")
    fig.axes[-1].set_xlabel("time (s)", fontsize=7)
    fig.subplots_adjust(left=0.1, right=0.97, top=0.95, bottom=0.07, hspace=0.35)  # x label above the footer
    return fig


def make_robot_report(model: Any, output: str | Path, logs: Sequence[Any] = (),
                      stage: Callable[[str], None] | None = None) -> int:
    """Draw every page of the robot file's ``model`` (:class:`~kukaid.identify.fitted.RobotFile`)
    before any file is created and write the PDF atomically; returns pages.  ``stage(text)`` is
    told what is being done (progress)."""
    params, source = model.params, model.source
    stage = stage or (lambda text: None)
    stage("drawing the parameter pages")
    figs = [page_base_parameters(params, source), page_friction_consistency(params, source)]
    for i, log in enumerate(logs):
        stage(f"predicting every axis on log {i + 1} of {len(logs)}")
        figs.append(page_prediction(model, log, source))
    stage(f"writing {len(figs)} pages")
    return write_report(output, figs, title="kukaid robot identification report")
