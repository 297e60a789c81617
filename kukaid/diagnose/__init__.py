"""Discrepancy workflow: where model and data disagree, which physical effect is missing, refit.

:func:`diagnose` (compare -> find -> add and refit -> repeat) returns a :class:`Diagnosis`;
the effects are terms of the one joint-torque model (:mod:`kukaid.models.effects`, names fixed);
which to try and when one is plausible is :mod:`kukaid.diagnose.candidates`, the evidence of a
round :mod:`kukaid.diagnose.evidence`, the refit :mod:`kukaid.diagnose.refit`, the statistics
:mod:`kukaid.diagnose.selection`, the noise floor :mod:`kukaid.diagnose.noise`, the PDF pages
:mod:`kukaid.diagnose.plots`.

:func:`diagnose_model` is the one entry for a fitted model of either kind
(:class:`~kukaid.identify.fitted.FittedModel`): one axis, this workflow; a robot file,
:func:`kukaid.diagnose.robot.diagnose_robot`.  It returns the result (``lines()``,
``to_json()``, the refined ``params``) and the function that draws its PDF pages.
"""
from __future__ import annotations

from typing import Any, Callable, Sequence

from kukaid.diagnose.candidates import CANDIDATES, NAMES
from kukaid.diagnose.workflow import Diagnosis, Step, diagnose, diagnose_signals

#: options a robot file's diagnosis does not take, and why (it works as the robot fit did)
ROBOT_FIXED = {"axis": "it tests the candidate effects of every axis together",
               "cutoff": "it filters the logs as the robot fit did (the file's settings)",
               "alpha": "it names an effect by the drop of the held-out error it brings, not by a test at a "
                        "false-alarm probability"}


def diagnose_model(model: Any, logs: Sequence[Any], *, axis: int | None = None, cutoff: float | None = None,
                   alpha: float | None = None, max_steps: int = 4, stage: Callable[[str], None] | None = None,
                   warn: Callable[[str], None] | None = None) -> tuple[Any, Callable[[Any, Any], Any]]:
    """Diagnose ``model`` (:func:`kukaid.identify.fitted.load_model`) on ``logs`` (AxisLog objects,
    each checked by ``model.check`` first, then its ``model.warnings`` told to ``warn``); ``cutoff``,
    ``alpha`` (None: the default) as :func:`~kukaid.diagnose.workflow.diagnose` takes them; the
    axis is the model's (``axis`` only says one was asked for: a robot file refuses it).  Returns
    (result, draw(result, path)); the result's ``joints()`` gives each joint's figures."""
    from contextlib import nullcontext

    from kukaid.errors import OptionError
    from kukaid.identify.adequacy import unit_warnings
    from kukaid.identify.fitted import RobotFile, file_cutoff
    from kukaid.logs import check_each_recording_once

    stage = stage or (lambda text: None)
    robot = isinstance(model, RobotFile)
    for name, value in (("axis", axis), ("cutoff", cutoff), ("alpha", alpha)) if robot else ():
        if value is not None:
            raise OptionError(f"{model.source}: option --{name} does not apply to a robot parameter file (yet): "
                              f"{ROBOT_FIXED[name]}")
    for lg in logs:  # a one-axis model refuses a log without its axis (the --axis given, or the file's)
        model.check(lg)
    check_each_recording_once(logs)  # a copy of a held-out log among the others is no held-out check
    for lg in logs:
        for w in model.warnings(lg, str(lg.attrs.get("source_file", "log"))):
            (warn or (lambda text: None))(w)
    with file_cutoff(model) if cutoff is None else nullcontext():  # the file's cut-off, unless --cutoff
        if robot:
            from kukaid.diagnose.robot import diagnose_robot
            from kukaid.diagnose.robot_plots import write_robot_report

            stage("testing the candidate effects on held-out recordings")
            result = diagnose_robot(model.params, logs, model.robot, max_steps=max_steps)
            result.unit_doubt = any(unit_warnings(lg, a) for lg in logs for a in model.joints if a in lg.axes)
            return result, write_robot_report
        from kukaid.diagnose.plots import write_report

        return diagnose(model.params, logs, axis=model.axis, cutoff=cutoff, alpha=0.01 if alpha is None else alpha,
                        max_steps=max_steps, source=model.source, stage=stage), write_report


__all__ = ["diagnose", "diagnose_model", "diagnose_signals", "Diagnosis", "Step", "CANDIDATES", "NAMES"]
