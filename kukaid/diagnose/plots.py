"""PDF pages of a diagnosis: the table of steps, the residual against each effect's coordinate
before and after it was added, and the residual spectrum before and after the whole workflow."""
from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np

from kukaid.diagnose import candidates as C
from kukaid.diagnose.result import Diagnosis
from kukaid.atomic import atomic_path
from kukaid.models.torque import JointTorqueModel


def _binned(x: np.ndarray, y: np.ndarray, bins: int = 30) -> tuple[np.ndarray, np.ndarray]:
    ok = np.isfinite(x) & np.isfinite(y)
    x, y = x[ok], y[ok]
    if x.size < 2 or np.ptp(x) == 0:
        return np.zeros(0), np.zeros(0)
    edges = np.linspace(x.min(), x.max(), bins + 1)
    k = np.clip(np.digitize(x, edges) - 1, 0, bins - 1)
    cnt = np.bincount(k, minlength=bins)
    s = np.bincount(k, weights=y, minlength=bins)
    m = cnt > 0
    return 0.5 * (edges[:-1] + edges[1:])[m], s[m] / cnt[m]


def _unit(result: Diagnosis) -> str:
    return "N" if result.sigs and result.sigs[0].joint == "prismatic" else "N·m"


def page_table(result: Diagnosis) -> tuple[list, float]:
    """The summary pages: the diagnosis's lines wrapped to the page, continued on new pages, then the
    table of steps; and the height (figure fraction) left free at the bottom of the last page."""
    cols = ["step", "effect", "RMSE before", "RMSE after", "gap closed", "Wald", "p (corr.)"]
    cells = [[str(i + 1), s.name, f"{s.rmse_before:.4g}", f"{s.rmse_after:.4g}", f"{100 * s.gap_closed:.0f} %",
              f"{s.test.wald.stat:.1f}", f"{s.test.p_adjusted:.2g}"] for i, s in enumerate(result.steps)]
    return summary_pages(result.lines(), [(cols, cells)] if cells else [])


def summary_pages(lines: list[str], tables: list[tuple], title: str = "kukaid diagnose: the gap and the effects found",
                  row: float = 0.03) -> tuple[list, float]:
    """A4 pages of ``lines`` wrapped to the page, continued on new pages, then each table
    ``(column labels, rows)`` or ``(column labels, rows, column widths)``, ``row`` high per row
    (figure fraction); and the height left free at the bottom of the last page."""
    import matplotlib.pyplot as plt

    figs: list = []

    def new_page():
        fig = plt.figure(figsize=(8.27, 11.69))
        fig.text(0.05, 0.96, title + (" (continued)" if figs else ""), fontsize=14, weight="bold")
        figs.append(fig)
        return fig, 0.92

    fig, y = new_page()
    for ln in lines:  # wrapped to the page: 100 characters of 8 pt monospace are 480 pt of 595 pt
        for sub in textwrap.wrap(ln, 100, subsequent_indent=" " * (len(ln) - len(ln.lstrip()) + 2)) or [""]:
            if y < 0.05:
                fig, y = new_page()
            fig.text(0.05, y, sub, fontsize=8, family="monospace")
            y -= 0.015
        y -= 0.007
    for cols, cells, *widths in tables:
        if y - 0.1 < row * (len(cells) + 1):  # the table's rows would not fit below the text
            fig, y = new_page()
        h = min(max(0.05, y - 0.1), row * (len(cells) + 1))
        ax = fig.add_axes([0.05, y - 0.02 - h, 0.9, h])
        ax.axis("off")
        tab = ax.table(cellText=cells, colLabels=cols, bbox=[0.0, 0.0, 1.0, 1.0], colWidths=(widths or [None])[0])
        tab.auto_set_font_size(False)
        tab.set_fontsize(7)
        y -= 0.04 + h
    return figs, y


def _residual_rows(model: JointTorqueModel, result: Diagnosis):
    return [model.residual(s) for s in result.sigs]


def page_step(result: Diagnosis, k: int):
    import matplotlib.pyplot as plt

    step = result.steps[k]
    cand = C.get(step.name)
    nl = step.test.nl
    fig, axes = plt.subplots(2, 1, figsize=(8.27, 11.69), sharex=True)
    for ax, model, label in ((axes[0], step.model_before, "before"), (axes[1], step.model_after, "after")):
        xs, rs = [], []
        for s in result.sigs:
            x, xlabel = cand.coordinate(s, nl)
            xs.append(x[s.rows])
            rs.append(model.residual(s))
        x = np.concatenate(xs)
        r = np.concatenate(rs)
        ax.plot(x, r, ".", ms=1.5, alpha=0.4, label="residual (measured - predicted)")
        bx, by = _binned(x, r)
        ax.plot(bx, by, "-", lw=2, color="C3", label="binned mean")
        ax.axhline(0, color="k", lw=0.5)
        ax.set_ylabel(f"residual ({_unit(result)})")
        ax.set_title(f"{label} adding {step.name}: RMSE {np.sqrt(np.mean(r * r)):.4g} {_unit(result)}")
        ax.legend(loc="upper right", fontsize=8)
        ax.set_xlabel(xlabel)
    fig.suptitle(textwrap.fill(f"step {k + 1}: {step.name} - {cand.meaning}", 85), fontsize=11)
    return fig


def page_spectrum(result: Diagnosis, fig=None, top: float = 0.92):
    """The residual spectrum before and after, on ``fig`` below ``top`` (figure fraction) or on a new
    A4 page."""
    import matplotlib.pyplot as plt
    from scipy.signal import welch

    if fig is None:
        fig = plt.figure(figsize=(8.27, 11.69))
    ax = fig.add_axes([0.12, max(top - 0.42, 0.06), 0.82, 0.36])
    for model, label in ((result.model_given, "given model"), (result.model_final, "after diagnosis")):
        ps, f = [], None
        for s in result.sigs:
            full = np.zeros(s.n)
            full[s.rows] = model.residual(s)
            f, p = welch(full, fs=s.fs, nperseg=min(512, s.n))
            ps.append(p)
        ax.semilogy(f, np.mean(ps, axis=0), label=label)
    ax.axvline(result.sigs[0].cutoff, color="k", ls=":", lw=0.8, label="filter cut-off")
    ax.set_xlabel("frequency (Hz)")
    u = _unit(result)
    ax.set_ylabel(f"residual PSD ({u}²/Hz)" if u == "N" else f"residual PSD (({u})²/Hz)")
    ax.set_title("residual spectrum; noise floor " + (f"{result.noise_floor:.3g} {u} RMS" if result.noise_floor > 0
                                                       else "not known"))
    ax.legend()
    return fig


def write_report(result: Diagnosis, path: str | Path) -> None:
    """Write the diagnosis pages to ``path`` (PDF, atomically)."""
    def pages():
        figs, free = page_table(result)
        if free > 0.5:  # the spectrum fits below the summary
            page_spectrum(result, figs[-1], free)
        figs += [page_step(result, k) for k in range(len(result.steps))]
        if free <= 0.5:
            figs.append(page_spectrum(result))
        return figs

    write_pages(pages, path)


def write_pages(draw, path: str | Path) -> int:
    """Draw the pages (``draw()``: a list of figures, on the Agg backend) and write them as one PDF at
    ``path``, atomically (no file is left on failure); returns the number of pages."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.backends.backend_pdf import PdfPages

    figs = draw()
    try:
        with atomic_path(path) as tmp:
            with PdfPages(tmp) as pdf:
                for fig in figs:
                    pdf.savefig(fig)
    finally:
        for fig in figs:
            plt.close(fig)
    return len(figs)
