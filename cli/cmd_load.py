"""kukaid load: import a log from another source (CSV, MAT, KUKA Trace) into an HDF5 axis log."""
from __future__ import annotations

from pathlib import Path

import click


@click.command("load")
@click.argument("source", type=click.Path(dir_okay=False, path_type=Path))
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="Axis log to write (.h5, or .csv to convert back).")
@click.option("--time", "time_var", default=None, help="MAT: time variable (default 'time' or 't').")
@click.option("--q", "q_var", default=None, help="MAT: position variable.")
@click.option("--tau", "tau_var", default=None, help="MAT: torque (force) variable.")
@click.option("--q-cmd", "q_cmd_var", default=None, help="MAT: commanded position variable.")
@click.option("--tau-scale", type=float, default=None, help="MAT: torque scale (e.g. 35.15 N/V).")
@click.option("--tau-scale-var", default=None, help="MAT: scalar variable holding the torque scale (e.g. gtau).")
@click.option("--q-scale", type=float, default=1.0, show_default=True, help="MAT: position scale to rad (m).")
@click.option("--joint", type=click.Choice(["revolute", "prismatic"]), default="revolute", show_default=True,
              help="MAT: joint type (prismatic: metres and newtons).")
@click.option("--axis", type=int, default=1, show_default=True, help="MAT: axis number of the log.")
def command(source: Path, output: Path, time_var, q_var, tau_var, q_cmd_var, tau_scale, tau_scale_var, q_scale,
            joint, axis) -> None:
    """Convert SOURCE (CSV, HDF5, MAT; KUKA Trace where supported) to an axis log.

    MAT example (EMPS): kukaid load DATA_EMPS.mat --time t --q qm --tau vir --tau-scale-var gtau
    --q-cmd qg --joint prismatic --axis 1 -o emps.h5
    """
    from kukaid.io.axislog import read_log, write_csv, write_hdf5

    options = {}
    if source.suffix.lower() == ".mat":
        options = dict(time=time_var, q=q_var, tau=tau_var, q_cmd=q_cmd_var, tau_scale=tau_scale,
                       tau_scale_var=tau_scale_var, q_scale=q_scale, joint=joint, axis=axis)
    log = read_log(source, **options)
    if output.suffix.lower() == ".csv":
        write_csv(log, output)
    else:
        write_hdf5(log, output)
    click.echo(f"{output}: {log.n_samples} samples of axes {', '.join(f'A{a}' for a in log.axes)}, "
               f"{log.duration:.2f} s", err=True)
