"""kukaid validate: a parameter file's model evaluated on logs it was not fitted on."""
from __future__ import annotations

from pathlib import Path

import click

from kukaid_cli._util import AXIS, URDF


@click.command("validate")
@click.option("--params", "params_path", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="Parameter file whose model is evaluated.")
@click.argument("logs", nargs=-1, required=True, type=click.Path(dir_okay=False, path_type=Path))
@click.option("--axis", type=AXIS, default=None, help="KUKA axis number (default: the parameter file's).")
@click.option("--json", "as_json", is_flag=True, help="Print the result as JSON on stdout.")
@URDF
def command(params_path: Path, logs: tuple[Path, ...], axis: int | None, as_json: bool, urdf: Path | None) -> None:
    """Per axis RMSE, relative error ||tau - tau_hat|| / ||tau||, R² and samples of the model of
    --params on LOGS (pooled), pre-processed as its fit was.  Give logs the model was not fitted on."""
    import json

    from kukaid.diagnose.validate import table, to_json, validate
    from kukaid.identify.fitted import load_model, use_warnings
    from kukaid.jsonfile import jsonable
    from kukaid.logs import read_log

    model = load_model(params_path, axis, urdf)
    data = [read_log(p) for p in logs]
    scores = validate(model, data)
    for w in use_warnings(model, logs, data):
        click.echo(f"kukaid: warning: validate: {w}", err=True)
    if as_json:
        click.echo(json.dumps(jsonable(to_json(scores)), indent=2))
    else:
        for line in table(scores, model.unit):
            click.echo(line)
