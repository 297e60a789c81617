"""kukaid load: import a log from another source (CSV, MAT, KUKA Trace) into an HDF5 axis log."""
from __future__ import annotations

from pathlib import Path

import click


@click.command("load")
@click.argument("source", type=click.Path(dir_okay=False, path_type=Path))
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="Axis log to write (.h5, or .csv to convert back).")
def command(source: Path, output: Path) -> None:
    """Convert SOURCE (CSV, HDF5; MAT and KUKA Trace where supported) to an axis log."""
    from kukaid.io.axislog import read_log, write_csv, write_hdf5

    log = read_log(source)
    if output.suffix.lower() == ".csv":
        write_csv(log, output)
    else:
        write_hdf5(log, output)
    click.echo(f"{output}: {log.n_samples} samples of axes {', '.join(f'A{a}' for a in log.axes)}, "
               f"{log.duration:.2f} s", err=True)
