"""kukaid report: the identification report (PDF) of a parameter file and the logs behind it."""
from __future__ import annotations

from pathlib import Path

import click

_LOG = click.Path(dir_okay=False, path_type=Path)


@click.command("report")
@click.option("--params", "params", type=_LOG, required=True, help="Parameter file (kukaid.params/1 JSON).")
@click.option("--friction", "friction", multiple=True, type=_LOG,
              help="Friction experiment log (constant-velocity sweeps): friction page; repeatable.")
@click.option("--inertia", "inertia", multiple=True, type=_LOG,
              help="Inertia experiment log (sine): torque-prediction page; repeatable.")
@click.option("--presliding", type=_LOG, default=None, help="Pre-sliding log: hysteresis / Maxwell-slip page.")
@click.option("--log", "logs", multiple=True, type=_LOG,
              help="General log: torque-prediction (validation) page; repeatable.")
@click.option("--axis", type=int, default=None, help="Axis number (default: the parameter file's axis).")
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="PDF file to write.")
def command(params, friction, inertia, presliding, logs, axis, output) -> None:
    """Write a multi-page PDF: parameters with uncertainties, friction, torque prediction,
    pre-sliding hysteresis, parameter correlation and residuals (pages for the data given)."""
    import matplotlib

    matplotlib.use("Agg")
    from kukaid.report import make_report
    from kukaid_cli._util import check_outputs, check_suffix, stages

    check_suffix(output, ".pdf")
    check_outputs([output], [params, *friction, *inertia, presliding, *logs])
    stage = stages("report")
    if _robot_report(params, friction, inertia, presliding, logs, axis, output, stage):
        return

    warnings: list[str] = []
    n = make_report(params, output, friction=list(friction), inertia=list(inertia), presliding=presliding,
                    logs=list(logs), axis=axis, warnings=warnings, stage=stage)
    for w in warnings:
        click.echo(f"kukaid: warning: report: {w}", err=True)
    _written(output, n)


def _robot_report(params, friction, inertia, presliding, logs, axis, output, stage) -> bool:
    """A robot parameter file (kukaid.robot_params/1): its own report; False for any other file."""
    from kukaid.errors import ParamFileError
    from kukaid.jsonfile import read_json
    from kukaid.params import is_robot_params, validate_robot_params

    d = read_json(params, ParamFileError)
    if not is_robot_params(d):
        return False
    if friction or inertia or presliding or axis is not None:
        raise click.UsageError("a robot parameter file takes only --log (prediction pages)")
    from kukaid.logs import read_log
    from kukaid.report.robot import make_robot_report

    validate_robot_params(d, str(params))
    stage("reading the logs")
    n = make_robot_report(d, output, [read_log(p) for p in logs], source=str(params), stage=stage)
    _written(output, n)
    return True


def _written(output, n: int) -> None:
    click.echo(f"{output}: report written, {n} page{'s' if n != 1 else ''}", err=True)
