"""Page layout shared by the report's pages: an A4 figure with a title block, tables; the PDF writer."""
from __future__ import annotations

import textwrap
from pathlib import Path
from typing import Any, Sequence

from kukaid.report.data import A4, ReportData, ReportError


def _page(title: str, footer: str):
    """An A4 page with its title and a grey footer, both 10 pt or more from the edges."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=A4)
    fig.suptitle(title, fontsize=13, weight="bold", y=0.981)
    fig.text(0.5, 0.016, footer, ha="center", fontsize=7, color="0.4")
    return fig


def _new_figure(title: str, data: ReportData):
    return _page(title, f"kukaid report · {Path(data.source).name} · axis A{data.params.get('axis', '?')}")


def _subtitle(fig, text: str) -> None:
    """The line under a page's title, wrapped within the page (down from below the title)."""
    fig.text(0.06, 0.964, textwrap.fill(text, 125), fontsize=7.5, va="top")


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
