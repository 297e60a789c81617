"""kukaid show: the table of a parameter file (one axis or a whole robot), as fit printed it."""
from __future__ import annotations

from pathlib import Path

import click


@click.command("show")
@click.argument("file", type=click.Path(dir_okay=False, path_type=Path))
def command(file: Path) -> None:
    """Print the parameters of FILE, a parameter file of `kukaid fit` (kukaid.params/1, one axis)
    or `kukaid fit --robot` (kukaid.robot_params/1): the same table fit prints, checked as it is read."""
    from kukaid.identify.fitted import load_model

    click.echo(load_model(file).table())
