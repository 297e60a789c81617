"""Page 3: measured and predicted torque over time and the residual (eqs. 6-8)."""
from __future__ import annotations

from typing import Any

import numpy as np


from kukaid.report.data import PAPER_TORQUE_MSE, ReportData, _runs, predicted
from kukaid.report.layout import _new_figure, _subtitle


def page_prediction(data: ReportData, log: Any, pr: Any, role: str = "inertia"):
    """Measured vs predicted torque over time, the residual, and the motion (paper's torque figure)."""
    pred = predicted(data, log, pr)
    res = pr.tau - pred
    m = pr.dynamic
    mse = float(np.mean(res[m] ** 2)) if m.any() else float("nan")
    tu = data.tu
    t = pr.time - pr.time[0]
    seen = "in-sample" if id(log) in data.fitted_on else "validation"  # in-sample: the model was fitted on it
    title = (f"Torque prediction, inertia experiment (eqs. 6-8, {seen})" if role == "inertia"
             else f"Torque prediction on a general log ({seen})")
    fig = _new_figure(title, data)
    _subtitle(fig, str(pr.source))
    a1 = fig.add_axes([0.11, 0.62, 0.78, 0.30])
    a2 = fig.add_axes([0.11, 0.36, 0.78, 0.20], sharex=a1)
    a3 = fig.add_axes([0.11, 0.07, 0.78, 0.22], sharex=a1)
    pred_d = np.where(m, pred, np.nan)
    res_d = np.where(m, res, np.nan)
    a1.plot(t, pr.tau_raw, "-", color="0.75", lw=0.5, label="measured (raw)")
    a1.plot(t, pr.tau, "-", color="C0", lw=1.0, label="measured (filtered)")
    a1.plot(t, pred_d, "--", color="C3", lw=1.0,
            label=f"predicted {'m' if data.prismatic else 'Izz'} q̈ + gravity + F(q̇)"
                  + (f" + {', '.join(data.params['effects'])}" if data.params.get("effects") else "")
                  + " (dynamic samples)")
    a1.set_ylabel(f"force F ({tu})" if data.prismatic else f"torque Γ ({tu})")
    lo, hi = a1.get_ylim()
    a1.set_ylim(lo, hi + 0.25 * (hi - lo))  # headroom: the legend above the data, not over its peaks
    a1.legend(fontsize=7, loc="upper left", ncol=3)
    a1.grid(True, alpha=0.3)
    ref = "" if data.prismatic else f"; paper {PAPER_TORQUE_MSE} {data.tu2} (real data, reference)"
    a1.set_title(f"MSE on the {int(m.sum())} dynamic-mode samples: {mse:.4g} {data.tu2}{ref}", fontsize=8.5,
                 loc="left")
    a2.plot(t, res_d, "-", color="C2", lw=0.8, label="measured − predicted")
    a2.axhline(0, color="k", lw=0.5)
    for a, b in _runs(~m):
        a2.axvspan(t[a], t[min(b, t.size - 1)], color="0.85", lw=0)
    a2.set_ylabel(f"residual ({tu})")
    a2.grid(True, alpha=0.3)
    if m.any():
        lim = 1.3 * float(np.max(np.abs(res[m]))) + 1e-9
        a2.set_ylim(-lim, lim)
    a2.legend(fontsize=7, loc="upper right", title="grey: not compared (quasi-static / near a reversal)",
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
