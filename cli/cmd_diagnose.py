"""kukaid diagnose: where model and data disagree, which effect is missing, refit, the gap shrinking."""
from __future__ import annotations

from pathlib import Path

import click

from kukaid_cli._util import AXIS, URDF


@click.command("diagnose")
@click.option("--params", "params_path", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="Parameter file whose model is compared with the logs: one axis (kukaid.params/1) or a robot "
                   "(kukaid.robot_params/1, fit --robot).")
@click.option("--log", "logs", type=click.Path(dir_okay=False, path_type=Path), multiple=True, required=True,
              help="Axis log (HDF5 or CSV); repeat for several experiments.")
@click.option("--axis", type=AXIS, default=None, help="KUKA axis number (default: the parameter file's).")
@click.option("--json", "as_json", is_flag=True, help="Print the result as JSON on stdout.")
@click.option("--report", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Write PDF pages: the table of steps, the residual before and after each effect against its "
                   "coordinate, the spectrum (a robot file: a page per joint, also against time, the noise floor).")
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Write the refined parameter file (effects in 'effects', predicted with by validate and "
                   "report); an existing parameter file of the same kind (one axis, or a robot) is replaced (it is "
                   "derived from the logs), any other file only with --force.")
@click.option("--force", is_flag=True, help="Replace an existing -o file that is not a parameter file of this kind.")
@click.option("--cutoff", type=float, default=None, help="Comparison filter cut-off, Hz (default: the fit's).")
@click.option("--alpha", type=float, default=0.01, show_default=True,
              help="False-alarm probability per round (over all candidates).")
@click.option("--max-steps", type=int, default=4, show_default=True, help="At most this many effects are added.")
@URDF
def command(params_path: Path, logs: tuple[Path, ...], axis: int | None, as_json: bool, report: Path | None,
            output: Path | None, force: bool, cutoff: float | None, alpha: float, max_steps: int,
            urdf: Path | None) -> None:
    """Find the physical effects the model of --params misses in the --log data, add them, refit.

    Candidates: gravity_sine, torque_offset, position_ripple, thermal_drift,
    load_dependent_friction, backlash, stribeck, presliding, coupling.  An effect is named only if
    it is significant, physically plausible, and lowers the error on data its fit did not see
    (leave one log out from three logs, else held-out blocks).  Prints per step the effect, its
    parameters, RMSE before -> after and the evidence (in-sample and held out); says why
    candidates were not named, and when two are ambiguous.

    With a robot parameter file (fit --robot): candidates an A2-style counterbalance (a gas spring,
    one per joint that carries gravity), a payload at the flange, and per joint load-dependent
    friction, thermal friction (with a temperature channel) and a position ripple, the coupled wrist
    drives' friction (six axes) and gear elasticity of A1-A3; each joint's own
    terms are refitted with the candidate on the other logs (or blocks) and judged on the held-out
    one (logs the file was fitted on are left out when two others remain).  -o writes the robot file
    with the named effects in 'effects' (validate, show, report and diagnose read them), its terms
    refitted beside them on the logs; --report one page per joint: the held-out residual before and
    after against time and each effect's coordinate, the noise floor drawn.  Effects already in the
    file are held and not named again.  --axis, --cutoff and --alpha do not apply to a robot file.
    """
    from kukaid.diagnose import diagnose_model
    from kukaid.identify.fitted import load_model
    from kukaid.logs import read_log
    from kukaid.params import ROBOT_SCHEMA, SCHEMA
    from kukaid_cli._util import (check_outputs, check_suffix, given, option_in_data_error, refuse_other_kind,
                                  require_positive, stages)

    if not 0 < alpha < 1:
        raise click.BadParameter("must be in (0, 1)", param_hint="--alpha")
    if max_steps < 0:
        raise click.BadParameter("must be >= 0", param_hint="--max-steps")
    require_positive(("--cutoff", cutoff))
    check_suffix(output, ".json")
    check_suffix(report, ".pdf")
    check_outputs([output, report], [params_path, *logs])
    model = load_model(params_path, axis, urdf)
    # a parameter file of the same kind (derived from logs again); a robot fit is not lost to an axis file
    refuse_other_kind(output, force, ROBOT_SCHEMA if model.params.get("schema") == ROBOT_SCHEMA else SCHEMA)
    stage = stages("diagnose")
    stage("reading the logs")
    data = [read_log(p) for p in logs]
    with option_in_data_error(("--cutoff", cutoff is not None, "filter cut-off")):  # its limit: the log's rate
        result, draw = diagnose_model(model, data, axis=axis, cutoff=cutoff, alpha=alpha if given("alpha") else None,
                                      max_steps=max_steps, stage=stage,
                                      warn=lambda w: click.echo(f"kukaid: warning: diagnose: {w}", err=True))
    for w in _mismatch(result, params_path):
        click.echo(f"kukaid: warning: diagnose: {w}", err=True)
    _write(result, as_json, output, report, model.check_file, model.save, draw, stage)


def _mismatch(result, params_path: Path) -> list[str]:
    """As validate warns: an axis the file's model predicts with a relative error of 98 % or more (no better
    than predicting no torque: a model of another robot or axis, or torques in another unit), whose
    effects this diagnosis would otherwise go on to look for."""
    from kukaid.diagnose.validate import MISMATCH

    if hasattr(result, "in_sample"):  # a robot diagnosis: the file as it is, per joint
        pairs = list(zip(result.axes, result.in_sample))
    else:
        pairs = [(result.joints()[0]["axis"], result.rel_before)]
    return [f"the model of {params_path} does not describe these logs on A{a}: its relative error is "
            f"{100 * r:.3g} %, {'worse than' if r >= 1.0 else 'no better than'} predicting no torque; is it of another "
            "robot or axis, or in another unit? "
            "(kukaid validate names the log)" for a, r in pairs if r >= MISMATCH]


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
    refined = "refined parameters written" if result.steps else "parameters written as given (no effect named)"
    for path, what in ((output, refined), (report, "report written")):
        if path is not None:
            click.echo(f"{path}: {what}", err=True)
