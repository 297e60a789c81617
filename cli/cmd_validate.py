"""kukaid validate: a parameter file's model evaluated on logs it was not fitted on.

Minimal robot-only path (branch ``six``): ``kukaid.robot_params/1`` files. The single-axis
validation and the schema -> predictor seam live on branch ``diag``; joining them is one line
there (``PREDICTORS["kukaid.robot_params/1"] = "kukaid.identify.robot_fit:robot_predictor"``)."""
from __future__ import annotations

from pathlib import Path

import click


@click.command("validate")
@click.option("--params", "params_path", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="Parameter file whose model is evaluated (kukaid.robot_params/1).")
@click.argument("logs", nargs=-1, required=True, type=click.Path(dir_okay=False, path_type=Path))
@click.option("--json", "as_json", is_flag=True, help="Print the result as JSON on stdout.")
def command(params_path: Path, logs: tuple[Path, ...], as_json: bool) -> None:
    """Per axis relative error ||tau - tau_hat|| / ||tau|| and RMS error of the model of --params
    on LOGS (pooled), pre-processed as its fit was. Give logs the model was not fitted on."""
    import json

    from kukaid.identify.robot_fit import validate_robot
    from kukaid.jsonfile import jsonable
    from kukaid.logs import read_log
    from kukaid.params import load_robot_params

    params = load_robot_params(params_path)
    res = validate_robot(params, [read_log(p) for p in logs])
    if as_json:
        click.echo(json.dumps(jsonable(res), indent=2))
        return
    click.echo(f"{'axis':<5} {'rel. error':>10} {'RMS error':>10} {'RMS torque':>10}  (N*m)")
    for a, r in res["axes"].items():
        click.echo(f"{a:<5} {100 * r['relative_error']:>9.1f}% {r['rms_error']:>10.4g} {r['rms_torque']:>10.4g}")
    click.echo(f"{'mean':<5} {100 * res['mean_relative_error']:>9.1f}%")
