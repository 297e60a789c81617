"""kukaid report: the identification report (PDF) of a parameter file and the logs behind it."""
from __future__ import annotations

from pathlib import Path

import click

from kukaid_cli._util import AXIS, URDF

_LOG = click.Path(dir_okay=False, path_type=Path)


@click.command("report")
@click.option("--params", "params", type=_LOG, required=True, help="Parameter file (JSON: kukaid.params/1, or kukaid.robot_params/1 from fit --robot).")
@click.option("--friction", "friction", multiple=True, type=_LOG,
              help="Friction experiment log (constant-velocity sweeps): friction page; repeatable.")
@click.option("--inertia", "inertia", multiple=True, type=_LOG,
              help="Inertia experiment log (sine): torque-prediction page; repeatable.")
@click.option("--presliding", type=_LOG, default=None, help="Pre-sliding log: hysteresis / Maxwell-slip page.")
@click.option("--log", "logs", multiple=True, type=_LOG,
              help="General log: torque-prediction (validation) page; repeatable.")
@click.option("--axis", type=AXIS, default=None, help="Axis number (default: the parameter file's axis).")
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="PDF file to write.")
@URDF
def command(params, friction, inertia, presliding, logs, axis, output, urdf) -> None:
    """Write a multi-page PDF: parameters with uncertainties, friction, torque prediction,
    pre-sliding hysteresis, parameter correlation and residuals (pages for the data given)."""
    import matplotlib

    matplotlib.use("Agg")
    from kukaid.identify.fitted import load_model
    from kukaid.report import report_model
    from kukaid_cli._util import check_outputs, check_suffix, stages

    check_suffix(output, ".pdf")
    check_outputs([output], [params, *friction, *inertia, presliding, *logs])
    stage = stages("report")
    warnings: list[str] = []
    model = load_model(params, axis, urdf)
    from kukaid.logs import read_log

    general = [read_log(p) for p in logs]  # read once: the report's prediction pages and the check below
    n = report_model(model, output, friction=list(friction), inertia=list(inertia),
                     presliding=presliding, logs=general, axis=axis, warnings=warnings, stage=stage)
    if logs:  # a model of another robot or axis, or another unit, as validate says it (its prediction pages show it)
        from kukaid.diagnose.validate import mismatch_warnings, validate
        from kukaid.errors import KukaidError

        per_log: list = []
        try:
            validate(model, general, per_log=per_log)
        except KukaidError:  # the report is written: what validate cannot compare, it says itself
            per_log = []
        warnings.extend(mismatch_warnings(per_log, logs, params, model.unit))
    for w in warnings:
        click.echo(f"kukaid: warning: report: {w}", err=True)
    click.echo(f"{output}: report written, {n} page{'s' if n != 1 else ''}", err=True)
