"""Figures of an admittance run (matplotlib, written to a PDF)."""
from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from kukaid.atomic import atomic_path


def plot_run(data: dict[str, np.ndarray], metrics: dict[str, Any], path: str | Path, title: str = "") -> None:
    """Four panels: torques (Γr, true external), position and reference, speed, damping/mode."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.backends.backend_pdf import PdfPages

    t = data["time"]
    fig, ax = plt.subplots(4, 1, figsize=(8.3, 10.5), sharex=True)
    a = ax[0]
    a.plot(t, data["gamma_r"], label="Γr (estimated)", lw=1)
    if np.any(np.isfinite(data["tau_ext_true"])):
        a.plot(t, data["tau_ext_true"], label="external torque (truth)", lw=1, ls="--")
    thr = metrics.get("threshold")
    if thr:
        for s in (1, -1):
            a.axhline(s * thr, color="0.6", lw=0.6, ls=":")
    det = data["detected"].astype(bool)
    if det.any():
        a.fill_between(t, 0, 1, where=det, transform=a.get_xaxis_transform(), color="C2", alpha=0.12,
                       label="detected")
    a.set_ylabel("torque, N·m")
    a.legend(loc="upper right", fontsize=8)
    a = ax[1]
    a.plot(t, np.degrees(data["q"]), label="q measured", lw=1)
    a.plot(t, np.degrees(data["q_cmd"]), label="reference sent", lw=1, ls="--")
    a.set_ylabel("angle, deg")
    a.legend(loc="upper right", fontsize=8)
    a = ax[2]
    a.plot(t, data["sigma_dot"], lw=1, label="σ̇")
    a.set_ylabel("reference speed, rad/s")
    a = ax[3]
    a.plot(t, data["D"], lw=1, label="D")
    a.set_ylabel("damping, N·m·s/rad")
    a2 = a.twinx()
    a2.step(t, data["dynamic"].astype(float), where="post", color="C3", lw=0.6, alpha=0.6)
    a2.set_yticks([0, 1], ["quasi-static", "dynamic"])
    a.set_xlabel("time, s")
    keys = ("damping", "detection_delay", "residual_rmse", "mean_sq_dgamma", "mean_cost", "displacement",
            "settled", "status")
    txt = ", ".join(f"{k} = {metrics[k]:.4g}" if isinstance(metrics.get(k), float) else f"{k} = {metrics.get(k)}"
                    for k in keys if k in metrics)
    fig.suptitle((title + "\n" if title else "") + txt, fontsize=8)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        with PdfPages(tmp) as pdf:
            pdf.savefig(fig)
    plt.close(fig)
