"""kukaid load: import a log from another source (CSV, MAT, KUKA Trace) into an HDF5 axis log."""
from __future__ import annotations

from pathlib import Path

import click

#: Output suffix -> format.
OUTPUT_FORMATS = {".h5": "hdf5", ".hdf5": "hdf5", ".csv": "csv"}
#: Options that only a MAT source uses (parameter name -> option).
MAT_OPTIONS = {"time_var": "--time", "q_var": "--q", "tau_var": "--tau", "q_cmd_var": "--q-cmd",
               "tau_scale": "--tau-scale", "tau_scale_var": "--tau-scale-var", "q_scale": "--q-scale",
               "time_scale": "--time-scale", "sample_time": "--sample-time", "joint": "--joint", "axis": "--axis"}


@click.command("load")
@click.argument("source", type=click.Path(dir_okay=False, path_type=Path))
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="Axis log to write: .h5/.hdf5 (HDF5), or .csv to convert back.")
@click.option("--force", is_flag=True, help="Replace an existing output file (never the input).")
@click.option("--time", "time_var", default=None, help="MAT: time variable (default 'time' or 't').")
@click.option("--q", "q_var", default=None, help="MAT: position variable.")
@click.option("--tau", "tau_var", default=None, help="MAT: torque (force) variable.")
@click.option("--q-cmd", "q_cmd_var", default=None, help="MAT: commanded position variable.")
@click.option("--tau-scale", type=float, default=None,
              help="MAT: torque scale, a finite non-zero number (e.g. 35.15 N/V); not with --tau-scale-var.")
@click.option("--tau-scale-var", default=None,
              help="MAT: scalar variable holding the torque scale (e.g. gtau); not with --tau-scale.")
@click.option("--q-scale", type=float, default=1.0, show_default=True,
              help="MAT: position scale to rad (m), finite and non-zero (0.0174533 for degrees).")
@click.option("--time-scale", type=float, default=1.0, show_default=True,
              help="MAT: time scale to seconds, positive (0.001 for milliseconds).")
@click.option("--sample-time", type=float, default=None,
              help="MAT: sample interval, s, when the file has no time variable.")
@click.option("--joint", type=click.Choice(["revolute", "prismatic"]), default="revolute", show_default=True,
              help="MAT: joint type (prismatic: metres and newtons).")
@click.option("--axis", type=int, default=1, show_default=True, help="MAT: axis number of the log.")
def command(source: Path, output: Path, force: bool, time_var, q_var, tau_var, q_cmd_var, tau_scale, tau_scale_var,
            q_scale, time_scale, sample_time, joint, axis) -> None:
    """Convert SOURCE (CSV, HDF5, MAT, KUKA Trace .dat) to an axis log.

    The output is never the input file, and an existing output is replaced only with --force.

    MAT example (EMPS): kukaid load DATA_EMPS.mat --time t --q qm --tau vir --tau-scale-var gtau
    --q-cmd qg --joint prismatic --axis 1 -o emps.h5
    """
    from click.core import ParameterSource

    from kukaid.errors import KukaidError
    from kukaid_cli._util import check_outputs, check_suffix, refuse_overwrite

    # before anything is read or written: the output's format, that it is not the input, no overwrite
    check_suffix(output, *OUTPUT_FORMATS)
    check_outputs([output], [source])
    refuse_overwrite(output, force)
    fmt = OUTPUT_FORMATS[output.suffix.lower()]
    is_mat = source.suffix.lower() == ".mat"
    if not is_mat:
        ctx = click.get_current_context()
        given = [opt for name, opt in MAT_OPTIONS.items()
                 if ctx.get_parameter_source(name) not in (None, ParameterSource.DEFAULT)]
        if given:
            raise KukaidError(f"{source}: option {given[0]} is for MAT (.mat) sources")

    from kukaid.logs import read_log, write_csv, write_hdf5

    options = {}
    if is_mat:
        options = dict(time=time_var, q=q_var, tau=tau_var, q_cmd=q_cmd_var, tau_scale=tau_scale,
                       tau_scale_var=tau_scale_var, q_scale=q_scale, time_scale=time_scale, sample_time=sample_time,
                       joint=joint, axis=axis)
    log = read_log(source, **options)
    if fmt == "csv":
        write_csv(log, output)
    else:
        write_hdf5(log, output)
    click.echo(f"{output}: {log.n_samples} samples of axes {', '.join(f'A{a}' for a in log.axes)}, "
               f"{log.duration:.2f} s", err=True)

