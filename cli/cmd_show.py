"""kukaid show: the table of a parameter file (one axis or a whole robot), as fit printed it."""
from __future__ import annotations

from pathlib import Path

import click

from kukaid_cli._util import URDF


@click.command("show")
@click.argument("file", type=click.Path(dir_okay=False, path_type=Path))
@URDF
def command(file: Path, urdf: Path | None) -> None:
    """Print the parameters of FILE, a parameter file of `kukaid fit` (kukaid.params/1, one axis)
    or `kukaid fit --robot` (kukaid.robot_params/1): the same table fit prints, checked as it is read."""
    from kukaid.identify.fitted import load_model

    click.echo(load_model(file, urdf=urdf, need_urdf=False).table())  # the table needs no URDF (masses alone)
