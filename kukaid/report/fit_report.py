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
Each page is a module of this package (:mod:`.parameters`, :mod:`.friction`, :mod:`.prediction`,
:mod:`.presliding`, :mod:`.correlation`); :mod:`.data` reads the inputs, :mod:`.layout` draws and writes.

Units: SI inside; figures show N·m, rad/s, rad (mrad for pre-sliding displacements).
"""
from __future__ import annotations

from pathlib import Path
from typing import Any, Callable, Sequence

from kukaid.report.correlation import page_correlation
from kukaid.report.data import ReportData, load_report_data
from kukaid.report.friction import page_friction
from kukaid.report.layout import write_report
from kukaid.report.parameters import page_parameters
from kukaid.report.prediction import page_prediction
from kukaid.report.presliding import page_presliding


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


def make_report(params: dict | str | Path, output: str | Path, friction: Sequence[Any] = (),
                inertia: Sequence[Any] = (), presliding: Any = None, logs: Sequence[Any] = (),
                axis: int | None = None, warnings: list[str] | None = None,
                stage: Callable[[str], None] | None = None, source: str | None = None) -> int:
    """Load, build and write the report (see :func:`load_report_data`; ``source`` names a
    dictionary ``params``); returns the page count.
    ``warnings`` (a list) gets the lines the user should read (:attr:`ReportData.warnings`);
    ``stage(text)`` is told what is being done (progress).

    Every input is read and every page drawn before the output file is created, so bad input
    raises a :class:`~kukaid.errors.KukaidError` and leaves no PDF.
    """
    stage = stage or (lambda text: None)
    stage("reading the logs and pre-processing them as the fit did")
    data = load_report_data(params, friction, inertia, presliding, logs, axis, source)
    if warnings is not None:
        warnings.extend(data.warnings)
    stage("drawing the pages")
    figs = build_report(data)
    stage(f"writing {len(figs)} pages")
    return write_report(output, figs)
