"""Figures of admittance runs (matplotlib, written to a PDF).

:func:`plot_runs` draws what the paper's hand-guiding figures show, one column per run (both
controllers side by side on the same operator): the torque residual Γr (with the true hand
torque in simulation and the detection), the damping (with the stability monitor's floor and
when it acted), the reference velocity σ̇, and the position; below, a table of the metrics.
"""
from __future__ import annotations

import math
import textwrap
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from kukaid.atomic import atomic_path

_TABLE_KEYS = (("status", "status"), ("xi", "mean ξ (Γr, window)"), ("dgamma2", "mean dΓr² (window)"),
               ("xi_true", "mean ξ (true hand torque)"), ("dgamma2_true", "mean dΓ² (true)"),
               ("residual_rmse", "Γr RMSE vs truth, N·m"), ("false_after_release", "detections after release"),
               ("end_error", "end error (of the move)"), ("D_range", "D range, N·m·s/rad"),
               ("grip_stiffness", "grip stiffness est., N·m/rad"), ("stability_events", "stability events"),
               ("first_event", "first stability event"))


def _fmt(v: Any) -> str:
    if isinstance(v, bool):
        return str(v)
    if isinstance(v, float):
        return "—" if math.isnan(v) else f"{v:.4g}"
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_fmt(x) for x in v) + "]"
    return textwrap.shorten(str(v), 38, placeholder="…")


def plot_runs(runs: Sequence[tuple[str, dict[str, np.ndarray], dict[str, Any]]], path: str | Path,
              title: str = "") -> None:
    """One column per ``(label, data, metrics)``: Γr, damping, σ̇, position; a metrics table below."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.backends.backend_pdf import PdfPages

    n = len(runs)
    fig = plt.figure(figsize=(11.69, 8.27) if n > 1 else (8.27, 11.69))
    gs = fig.add_gridspec(5, n, height_ratios=[1, 1, 1, 1, 1.8], hspace=0.4, wspace=0.25,
                          left=0.08 if n > 1 else 0.12, right=0.98, top=0.9, bottom=0.05)
    axes = [[fig.add_subplot(gs[r, c]) for r in range(4)] for c in range(n)]
    for c in range(1, n):  # same scales side by side
        for r in range(4):
            axes[c][r].sharex(axes[0][r])
            axes[c][r].sharey(axes[0][r])
    for c, (label, d, m) in enumerate(runs):
        t = d["time"]
        a = axes[c][0]
        a.set_title(textwrap.shorten(label, 70, placeholder="…"), fontsize=9)
        a.plot(t, d["gamma_r"], lw=0.9, label="Γr (estimated)")
        if np.any(np.isfinite(d["tau_ext_true"])):
            a.plot(t, d["tau_ext_true"], lw=0.8, ls="--", label="hand torque (truth)")
        det = d["detected"].astype(bool)
        if det.any():
            a.fill_between(t, 0, 1, where=det, transform=a.get_xaxis_transform(), color="C2", alpha=0.12,
                           label="detected")
        a.set_ylabel("torque, N·m", fontsize=8)
        a.legend(loc="best", fontsize=6)  # where it covers the fewest samples
        a = axes[c][1]
        a.plot(t, d["D"], lw=0.9, label="D in use")
        if "D_floor" in d and np.any(d["D_floor"] > 0):
            a.plot(t, np.where(d["D_floor"] > 0, d["D_floor"], np.nan), lw=0.8, color="C3",
                   label="stability floor")
        if "D_grip" in d and np.any(d["D_grip"] > 0):
            a.plot(t, np.where(d["D_grip"] > 0, d["D_grip"], np.nan), lw=0.8, color="C4", ls="--",
                   label="grip floor")
        for e in m.get("stability_log", []):
            a.axvline(e["time"], color="C3", lw=0.5, ls=":")
        a.set_ylabel("damping,\nN·m·s/rad", fontsize=8)
        a.legend(loc="best", fontsize=6)  # where it covers the fewest samples
        a = axes[c][2]
        a.plot(t, d["sigma_dot"], lw=0.9)
        a.set_ylabel("reference velocity\nσ̇, rad/s", fontsize=8)
        a = axes[c][3]
        a.plot(t, np.degrees(d["q"]), lw=0.9, label="q measured")
        a.plot(t, np.degrees(d["q_cmd"]), lw=0.8, ls="--", label="reference sent")
        goal = m.get("goal")
        if goal is not None and math.isfinite(goal):
            a.axhline(math.degrees(goal), color="0.5", lw=0.6, ls=":", label="person's goal")
        a.set_ylabel("position, deg", fontsize=8)
        a.set_xlabel("time, s", fontsize=8)
        a.legend(loc="best", fontsize=6)
        for a in axes[c]:
            a.tick_params(labelsize=7)
    # metrics table across the bottom row, filling it (a margin below the table, whatever the rows)
    ta = fig.add_subplot(gs[4, :])
    ta.axis("off")
    metrics = []
    for _, _, m in runs:
        ev = m.get("stability_log") or []
        metrics.append({**m, "first_event": (f"t = {ev[0]['time']:.2f} s: "
                                             + ("grip" if "grip stiffness" in ev[0]["reason"] else "oscillation")
                                             + f", floor {ev[0]['D_floor']:.0f}") if ev else "none"})
    rows = [(name, [_fmt(m.get(k, "—")) for m in metrics]) for k, name in _TABLE_KEYS
            if any(k in m for m in metrics)]
    tab = ta.table(cellText=[[name, *vals] for name, vals in rows],
                   colLabels=["", *[textwrap.shorten(lbl, 40, placeholder="…") for lbl, _, _ in runs]],
                   bbox=[0.0, 0.0, 1.0, 1.0], cellLoc="left", colWidths=[0.28] + [0.72 / n] * n)
    tab.auto_set_font_size(False)
    tab.set_fontsize(7)
    fig.suptitle(textwrap.fill(title, 110 if n > 1 else 85) if title else "", fontsize=10, y=0.97)
    with atomic_path(path) as tmp:
        with PdfPages(tmp) as pdf:
            pdf.savefig(fig)
    plt.close(fig)


def plot_run(data: dict[str, np.ndarray], metrics: dict[str, Any], path: str | Path, title: str = "") -> None:
    """A single run (see :func:`plot_runs`)."""
    plot_runs([(str(metrics.get("damping", "run")), data, metrics)], path, title=title)
