"""kukaid diagnose: where model and data disagree, which effect is missing, refit, the gap shrinking."""
from __future__ import annotations

from pathlib import Path

import click


@click.command("diagnose")
@click.option("--params", "params_path", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="Parameter file whose model is compared with the logs: one axis (kukaid.params/1) or a robot "
                   "(kukaid.robot_params/1, fit --robot).")
@click.option("--log", "logs", type=click.Path(dir_okay=False, path_type=Path), multiple=True, required=True,
              help="Axis log (HDF5 or CSV); repeat for several experiments.")
@click.option("--axis", type=int, default=None, help="KUKA axis number (default: the parameter file's).")
@click.option("--json", "as_json", is_flag=True, help="Print the result as JSON on stdout.")
@click.option("--report", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Write PDF pages: the table of steps, the residual before and after each effect against its "
                   "coordinate, the spectrum (a robot file: a page per joint, also against time, the noise floor).")
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Write the refined parameter file (effects in 'effects', predicted with by validate and "
                   "report); an existing parameter file is replaced (it is derived from the logs), any other file "
                   "only with --force.")
@click.option("--force", is_flag=True, help="Replace an existing -o file that is not a parameter file.")
@click.option("--cutoff", type=float, default=None, help="Comparison filter cut-off, Hz (default: the fit's).")
@click.option("--alpha", type=float, default=0.01, show_default=True,
              help="False-alarm probability per round (over all candidates).")
@click.option("--max-steps", type=int, default=4, show_default=True, help="At most this many effects are added.")
def command(params_path: Path, logs: tuple[Path, ...], axis: int | None, as_json: bool, report: Path | None,
            output: Path | None, force: bool, cutoff: float | None, alpha: float, max_steps: int) -> None:
    """Find the physical effects the model of --params misses in the --log data, add them, refit.

    Candidates: gravity_sine, torque_offset, position_ripple, thermal_drift,
    load_dependent_friction, backlash, stribeck, presliding, coupling.  An effect is named only if
    it is significant, physically plausible, and lowers the error on data its fit did not see
    (leave one log out from three logs, else held-out blocks).  Prints per step the effect, its
    parameters, RMSE before -> after and the evidence (in-sample and held out); says why
    candidates were not named, and when two are ambiguous.

    With a robot parameter file (fit --robot): candidates an A2-style counterbalance (a gas spring,
    one per joint that carries gravity), a payload at the flange, and per joint load-dependent
    friction, thermal friction (with a temperature channel) and a position ripple; each joint's own
    terms are refitted with the candidate on the other logs (or blocks) and judged on the held-out
    one (logs the file was fitted on are left out when two others remain).  -o writes the robot file
    with the named effects in 'effects' (validate, show, report and diagnose read them), its terms
    refitted beside them on the logs; --report one page per joint: the held-out residual before and
    after against time and each effect's coordinate, the noise floor drawn.  Effects already in the
    file are held and not named again.  --axis, --cutoff and --alpha do not apply to a robot file.
    """
    from kukaid.errors import KukaidError
    from kukaid.logs import read_log
    from kukaid_cli._util import (check_outputs, check_suffix, option_in_data_error, refuse_other_kind,
                                  require_positive, stages)
    from kukaid.params import ROBOT_SCHEMA, SCHEMA, is_robot_params, load_any_params, save_params, validate_params
    from kukaid.diagnose.plots import write_report
    from kukaid.diagnose.workflow import diagnose

    if not 0 < alpha < 1:
        raise click.BadParameter("must be in (0, 1)", param_hint="--alpha")
    if max_steps < 0:
        raise click.BadParameter("must be >= 0", param_hint="--max-steps")
    require_positive(("--cutoff", cutoff))
    check_suffix(output, ".json")
    check_suffix(report, ".pdf")
    check_outputs([output, report], [params_path, *logs])
    refuse_other_kind(output, force, SCHEMA, ROBOT_SCHEMA)
    params = load_any_params(params_path)
    stage = stages("diagnose")
    if is_robot_params(params):
        _robot(click.get_current_context(), params, logs, as_json, max_steps, output, report, stage)
        return
    stage("reading the logs")
    data = [read_log(p) for p in logs]
    from kukaid.identify.adequacy import pushed_log_warnings

    for p, lg in zip(logs, data):
        for w in pushed_log_warnings(lg, str(p)):
            click.echo(f"kukaid: warning: diagnose: {w}", err=True)
    if axis is not None:
        for p, lg in zip(logs, data):
            if axis not in lg.axes:
                raise KukaidError(f"{p}: axis A{axis} is not in the log (axes: {list(lg.axes)})")
    with option_in_data_error(("--cutoff", cutoff is not None, "filter cut-off")):  # its limit: the log's rate
        result = diagnose(params, data, axis=axis, cutoff=cutoff, alpha=alpha, max_steps=max_steps,
                          source=str(params_path), stage=stage)
    _write(result, as_json, output, report, validate_params, save_params, write_report, stage)


def _write(result, as_json: bool, output, report, check, save, draw, stage) -> None:
    """The refined parameter file (``check``ed first: a problem names -o, not a temporary file;
    ``save(path, params)``) and the report (``draw(result, path)``), both or neither; then the
    result on stdout (JSON with --json, else its lines)."""
    import json

    from kukaid.atomic import atomic_paths
    from kukaid.jsonfile import jsonable

    if output is not None:
        check(jsonable(result.params), str(output))
    with atomic_paths(*[p for p in (output, report) if p is not None]) as tmps:  # both or neither
        tmp = iter(tmps)
        if output is not None:
            save(next(tmp), result.params)
        if report is not None:
            stage("drawing the report")
            draw(result, next(tmp))
    if as_json:
        click.echo(json.dumps(jsonable(result.to_json()), indent=2))
    else:
        for line in result.lines():
            click.echo(line)
    for path, what in ((output, "refined parameters"), (report, "report")):
        if path is not None:
            click.echo(f"{path}: {what} written", err=True)


def _robot(ctx: click.Context, params: dict, logs, as_json: bool, max_steps: int, output, report, stage) -> None:
    """``kukaid diagnose --params robot.json``: the robot's candidates (kukaid.diagnose.robot)."""
    from kukaid.diagnose.robot import diagnose_robot
    from kukaid.diagnose.robot_plots import write_robot_report
    from kukaid.logs import read_log
    from kukaid.params import save_robot_params, validate_robot_params
    from kukaid_cli._util import given

    for name, flag, why in (("axis", "--axis", "it tests the candidate effects of every axis together"),
                            ("cutoff", "--cutoff", "it filters the logs as the robot fit did (the file's settings)"),
                            ("alpha", "--alpha", "it names an effect by the drop of the held-out error it brings, "
                                                 "not by a test at a false-alarm probability")):
        if given(name, ctx):
            raise click.UsageError(f"option {flag} does not apply to a robot parameter file (yet): {why}")
    from kukaid.identify.robot_fit import check_torque_scale
    from kukaid.models.robot import RobotModel

    stage("reading the logs")
    data = [read_log(p) for p in logs]
    robot = RobotModel(params["robot"]["urdf"])
    for lg in data:  # torques in another unit, as fit and validate refuse them
        check_torque_scale(lg, robot)
    stage("testing the candidate effects on held-out recordings")
    result = diagnose_robot(params, data, robot, max_steps=max_steps)
    _write(result, as_json, output, report, validate_robot_params, save_robot_params, write_robot_report, stage)
