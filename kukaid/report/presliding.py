"""Page 4: pre-sliding torque against displacement and the Maxwell-slip model replayed (eqs. 9-10, 12)."""
from __future__ import annotations

from typing import Any

import numpy as np


from kukaid.report.data import (ReportData, ReportError, _model, _runs)
from kukaid.report.layout import _new_figure, _subtitle


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
    _subtitle(fig, str(data.presliding[1].source))
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
