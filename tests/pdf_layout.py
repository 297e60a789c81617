"""Layout checks of the PDF pages' figures, by matplotlib's own text extents (no PDF reader).

:func:`layout_problems` draws a figure and names every text or table closer than ``margin`` points
to an edge of the page (or past it), every table cell's text wider than its cell, and the
figure-level texts (title, subtitles) that overlap one another; :func:`capture_pages` checks every
page a command writes, through ``PdfPages.savefig``.
"""
from __future__ import annotations

from typing import Any

MARGIN = 10.0  # pt


def layout_problems(fig: Any, margin: float = MARGIN) -> list[str]:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.table import Table

    if not isinstance(fig.canvas, FigureCanvasAgg):
        FigureCanvasAgg(fig)
    fig.canvas.draw()
    r = fig.canvas.get_renderer()
    W, H = fig.bbox.width, fig.bbox.height
    m = margin * fig.dpi / 72.0
    # the figure's own texts and each axes with what it draws (tick labels in view, labels, title,
    # legend, table): every Text object would include tick labels matplotlib keeps but does not draw
    top = [t for t in dict.fromkeys([*fig.texts, getattr(fig, "_suptitle", None)])  # title, subtitles, footer
           if t is not None and t.get_visible() and t.get_text().strip()]
    items = [(t.get_text(), t) for t in top]
    items += [(f"axes {a.get_title(loc='left') or a.get_title() or a.get_ylabel()}", a) for a in fig.axes
              if a.get_visible()]
    pt = 72.0 / fig.dpi
    out = []
    for s, a in items:
        b = a.get_tightbbox(r)
        if b.x0 < m or b.y0 < m or b.x1 > W - m or b.y1 > H - m:
            out.append(f"{s[:60]!r} at ({b.x0 * pt:.0f}, {b.y0 * pt:.0f}, {b.x1 * pt:.0f}, {b.y1 * pt:.0f}) pt "
                       f"of {W * pt:.0f} x {H * pt:.0f}")
    for tab in fig.findobj(Table):
        for c in tab.get_celld().values():
            t = c.get_text()
            if t.get_text().strip() and t.get_window_extent(r).width > c.get_window_extent(r).width:
                out.append(f"{t.get_text()[:60]!r} wider than its table cell")
    for i, a in enumerate(top):
        for b in top[i + 1:]:
            if a.get_window_extent(r).overlaps(b.get_window_extent(r)):
                out.append(f"{a.get_text()[:40]!r} overlaps {b.get_text()[:40]!r}")
    return out


def capture_pages(monkeypatch: Any) -> list[str]:
    """The layout problems of every page written through ``PdfPages.savefig`` from now on (a list
    that fills as pages are written)."""
    from matplotlib.backends.backend_pdf import PdfPages

    problems: list[str] = []
    save = PdfPages.savefig

    def savefig(self, figure=None, **kw):
        problems.extend(layout_problems(figure))
        return save(self, figure, **kw)

    monkeypatch.setattr(PdfPages, "savefig", savefig)
    return problems
