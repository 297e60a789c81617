"""kukaid validate: a parameter file's model evaluated on logs it was not fitted on."""
from __future__ import annotations

from pathlib import Path

import click

from kukaid_cli._util import AXIS, URDF


@click.command("validate")
@click.option("--params", "params_path", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="Parameter file whose model is evaluated.")
@click.argument("logs", nargs=-1, type=click.Path(dir_okay=False, path_type=Path))
@click.option("--log", "log_opts", type=click.Path(dir_okay=False, path_type=Path), multiple=True,
              help="Axis log, as diagnose and report take it; repeatable, and the same as giving it as LOGS.")
@click.option("--axis", type=AXIS, default=None, help="KUKA axis number (default: the parameter file's).")
@click.option("--json", "as_json", is_flag=True, help="Print the result as JSON on stdout.")
@click.option("--strict", is_flag=True,
              help="Exit with status 4 after the figures when there were warnings: above all a model that does not "
                   "describe the logs (an axis's relative error 98 % or more: another robot or axis, or another "
                   "unit), also a measured torque that does not vary (an empty torque column), a log it was "
                   "fitted on, other axes moving, a log pushed by hand.")
@URDF
def command(params_path: Path, logs: tuple[Path, ...], log_opts: tuple[Path, ...], axis: int | None,
            as_json: bool, strict: bool, urdf: Path | None) -> None:
    """Per axis RMSE, relative error ||tau - tau_hat|| / ||tau||, R² and samples of the model of
    --params on LOGS (pooled), pre-processed as its fit was.  Give logs the model was not fitted on,
    as LOGS or each with --log (as diagnose and report take them).

    An axis whose relative error is 98 % or more (the model's error as large as the torque itself:
    a model of another robot or axis, or torques in another unit) is warned about first; with
    --strict that, and any other warning, is exit status 4."""
    import json

    from kukaid.diagnose.validate import flat_warnings, mismatch_warnings, table, to_json, validate
    from kukaid.identify.fitted import load_model, use_warnings
    from kukaid.jsonfile import jsonable
    from kukaid.logs import check_each_recording_once, read_log
    from kukaid_cli._util import strict_exit

    logs = (*logs, *log_opts)
    if not logs:
        raise click.UsageError("Missing argument 'LOGS...' (or --log)")
    model = load_model(params_path, axis, urdf)
    data = [read_log(p) for p in logs]
    check_each_recording_once(data)  # pooled twice, it would count double: as fit and diagnose, refused
    per_log: list = []
    scores = validate(model, data, per_log=per_log)
    warnings = (flat_warnings(per_log, logs, scores, model.unit)
                + mismatch_warnings(per_log, logs, params_path, model.unit) + use_warnings(model, logs, data))
    for w in warnings:
        click.echo(f"kukaid: warning: validate: {w}", err=True)
    if as_json:
        click.echo(json.dumps(jsonable({**to_json(scores), "warnings": warnings}), indent=2))  # stderr has them too
    else:
        for line in table(scores, model.unit):
            click.echo(line)
    if strict:
        strict_exit("validate", warnings)
