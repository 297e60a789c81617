"""Reports: the identification report of a fitted model, a multi-page PDF (:func:`report_model`:
one axis, :mod:`kukaid.report.fit_report`; a robot, :mod:`kukaid.report.robot`)."""
from __future__ import annotations

from typing import Any, Callable, Sequence

from kukaid.report.data import ReportData, ReportError, load_report_data
from kukaid.report.fit_report import build_report, make_report
from kukaid.report.layout import write_report


def report_model(model: Any, output: Any, friction: Sequence[Any] = (), inertia: Sequence[Any] = (),
                 presliding: Any = None, logs: Sequence[Any] = (), axis: int | None = None,
                 warnings: list[str] | None = None, stage: Callable[[str], None] | None = None) -> int:
    """The report of a :class:`~kukaid.identify.fitted.FittedModel` (:func:`kukaid.identify.fitted.
    load_model`) and the logs given (paths, or logs read from them); returns the page count.  A robot
    file's report takes only general ``logs`` (a prediction page each): the experiment roles are one axis's."""
    from kukaid.errors import OptionError
    from kukaid.identify.fitted import RobotFile, file_cutoff, use_warnings

    if isinstance(model, RobotFile):
        refused = [f"--{name}" for name, given in (("friction", friction), ("inertia", inertia),
                                                   ("presliding", presliding), ("axis", axis is not None)) if given]
        if refused:  # as diagnose: the file, the option, why
            raise OptionError(f"{model.source}: option{'s' if len(refused) > 1 else ''} {', '.join(refused)} "
                              f"do{'' if len(refused) > 1 else 'es'} not apply to a robot parameter file: its report "
                              "takes only --log, a prediction page of every joint per log (the experiment roles and "
                              "--axis are a one-axis file's)")
        from kukaid.logs import read_log
        from kukaid.report.robot import make_robot_report

        (stage or (lambda text: None))("reading the logs")
        data = [x if hasattr(x, "tau") else read_log(x) for x in logs]
        for lg in data:
            model.check(lg)
        if warnings is not None:
            names = [lg.attrs.get("source_file", "log") if hasattr(x, "tau") else x for x, lg in zip(logs, data)]
            warnings.extend(use_warnings(model, names, data))  # validate's
        with file_cutoff(model):
            return make_robot_report(model, output, data, stage=stage)
    with file_cutoff(model):
        return make_report(model.params, output, friction=friction, inertia=inertia, presliding=presliding, logs=logs,
                           axis=axis, warnings=warnings, stage=stage, source=model.source)


__all__ = ["ReportData", "ReportError", "build_report", "load_report_data", "make_report", "report_model",
           "write_report"]
