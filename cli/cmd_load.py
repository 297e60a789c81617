"""kukaid load: import a log from another source (CSV, MAT, KUKA Trace) into an HDF5 axis log."""
from __future__ import annotations

from pathlib import Path

import click

from kukaid_cli._util import JSON_HELP

#: Output suffix -> format.
OUTPUT_FORMATS = {".h5": "hdf5", ".hdf5": "hdf5", ".csv": "csv"}
#: Options that only a MAT source uses (parameter name -> option).
MAT_OPTIONS = {"time_var": "--time", "q_var": "--q", "tau_var": "--tau", "q_cmd_var": "--q-cmd",
               "tau_scale": "--tau-scale", "tau_scale_var": "--tau-scale-var", "q_scale": "--q-scale",
               "time_scale": "--time-scale", "sample_time": "--sample-time", "joint": "--joint", "axis": "--axis"}
#: Options that only a KUKA Trace source (.dat/.r64) uses.
TRACE_OPTIONS = {"gear_ratio": "--gear-ratio", "time_base": "--time-base"}
TRACE_SUFFIXES = (".dat", ".r64")


@click.command("load")
@click.argument("source", type=click.Path(dir_okay=False, path_type=Path))
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="Axis log to write: .h5/.hdf5 (HDF5), or .csv to convert back.")
@click.option("--force", is_flag=True, help="Replace an existing output file (never the input).")
@click.option("--json", "as_json", is_flag=True, help=JSON_HELP)
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
              help="MAT: sample interval, s, when the file has no time variable (not with --time).")
@click.option("--joint", type=click.Choice(["revolute", "prismatic"]), default="revolute", show_default=True,
              help="MAT: joint type (prismatic: metres and newtons).")
@click.option("--axis", default="1", show_default=True,
              help="MAT: axis number of the log, or a list (1,2,3) for (samples, axes) arrays.")
@click.option("--gear-ratio", default=None,
              help="Trace: motor turns per axis turn, 'A1=-161,A2=153,...' or a JSON file {\"A1\": -161, ...}; "
                   "puts the drives' motor-side position and torque on the joint.")
@click.option("--time-base", type=click.Choice(["position", "finest", "common"]), default="position",
              show_default=True,
              help="Trace: position = the measured position's instants (others interpolated linearly), finest = "
                   "the shortest sample time, common = only instants every channel has (no interpolation).")
def command(source: Path, output: Path, force: bool, as_json: bool, time_var, q_var, tau_var, q_cmd_var, tau_scale, tau_scale_var,
            q_scale, time_scale, sample_time, joint, axis, gear_ratio, time_base) -> None:
    """Convert SOURCE (CSV, HDF5, MAT, KUKA Trace .dat/.r64) to an axis log.

    The output is never the input file, and an existing output is replaced only with --force.
    A KUKA Trace source is any file of the recording: every module beside it is read (each
    NextGenDrive#N, KRCIpo); the time base used is printed on stdout (with --json: in the
    JSON, and on stderr).

    MAT example (EMPS): kukaid load DATA_EMPS.mat --time t --q qm --tau vir --tau-scale-var gtau
    --q-cmd qg --joint prismatic --axis 1 -o emps.h5

    Trace example (KR C4): kukaid load Rec_NextGenDrive#1.dat --gear-ratio gear.json -o rec.h5
    """
    from kukaid.logs import format_suffix, read_log, write_csv, write_hdf5
    from kukaid_cli._util import check_outputs, check_suffix, given, refuse_overwrite, usage_errors

    # before anything is read or written: the output's format, that it is not the input (no overwrite: below)
    check_suffix(output, *OUTPUT_FORMATS)
    check_outputs([output], [source])
    fmt = OUTPUT_FORMATS[output.suffix.lower()]
    kind = format_suffix(source)  # also compressed: rec.mat.bz2
    is_mat, is_trace = kind == ".mat", kind in TRACE_SUFFIXES
    for options, applies, kind in ((MAT_OPTIONS, is_mat, "MAT (.mat)"),
                                   (TRACE_OPTIONS, is_trace, "KUKA Trace (.dat, .r64)")):
        typed = [opt for name, opt in options.items() if given(name)]
        if typed and not applies:
            raise click.UsageError(f"{source}: option {typed[0]} is for {kind} sources")

    options, hints = {}, []
    if is_mat:
        from kukaid.logs.matlog import check_mat_options

        if time_var is not None and sample_time is not None:
            raise click.UsageError(f"{source}: options --time and --sample-time contradict each other: the sample "
                                   "times come from the time variable, or are every --sample-time s; give one")
        with usage_errors():  # the options alone, before the file is read
            check_mat_options(source, tau_scale, tau_scale_var, q_scale, time_scale, sample_time)
        options = dict(time=time_var, q=q_var, tau=tau_var, q_cmd=q_cmd_var, tau_scale=tau_scale,
                       tau_scale_var=tau_scale_var, q_scale=q_scale, time_scale=time_scale, sample_time=sample_time,
                       joint=joint if given("joint") else None,
                       axis=_axes(source, axis), hints=hints)
    elif is_trace:
        from kukaid.logs.trace import is_gear_ratio_file, parse_gear_ratios

        if gear_ratio is not None and not is_gear_ratio_file(gear_ratio):
            with usage_errors():  # the ratios themselves, typed as the option's value
                gear_ratio = parse_gear_ratios(gear_ratio)
        options = dict(gear_ratio=gear_ratio, time_base=time_base, hints=hints)
    refuse_overwrite(output, force)  # after the options' checks: a wrong option is said first
    if source.suffix.lower() in (".h5", ".hdf5"):
        from kukaid.logs import read_hdf5

        log = read_hdf5(source, whole=True)  # the copy holds every row, or load says why not
    else:
        log = read_log(source, **options)
    if fmt == "csv":
        write_csv(log, output)
    else:
        write_hdf5(log, output)
    if "time_base_note" in log.attrs:  # with --json stdout is the JSON alone
        click.echo(log.attrs["time_base_note"], err=as_json)
    for h in hints:  # units the file leaves open, and the option that says them
        click.echo(f"kukaid: warning: load: {h}", err=True)
    hints += _implausible(source, log)
    if as_json:
        from kukaid_cli._util import echo_json

        echo_json({"output": str(output), "source": str(source), "samples": log.n_samples, "axes": list(log.axes),
                   "joint": list(log.joint), "duration": log.duration, "time_base": log.attrs.get("time_base"),
                   "time_base_note": log.attrs.get("time_base_note"), "warnings": hints})
    click.echo(f"{output}: {log.n_samples} samples of axes {', '.join(f'A{a}' for a in log.axes)}, "
               f"{log.duration:.2f} s", err=True)


def _axes(source: Path, text: str) -> int | list[int]:
    """--axis: one axis number, or a comma-separated list of them."""
    try:
        axes = [int(p) for p in str(text).split(",") if p.strip()]
    except ValueError:
        raise click.UsageError(f"{source}: --axis must be an axis number or a list such as 1,2,3; got {text!r}") from None
    if not axes:
        raise click.UsageError(f"{source}: --axis must name at least one axis")
    if len(set(axes)) != len(axes) or not all(1 <= a <= 12 for a in axes):
        raise click.UsageError(f"{source}: --axis must be distinct axis numbers 1 to 12; got {text!r}")
    return axes[0] if len(axes) == 1 and "," not in str(text) else axes



def _implausible(source: Path, log) -> list[str]:
    """A prismatic position beyond any linear track is probably a wrong --q-scale (revolute ones
    beyond 720 degrees are refused by the readers): a warning (printed and returned), the log is written."""
    import numpy as np

    from kukaid.logs.core import MAX_PRISMATIC_M

    out = []
    for c, (a, j) in enumerate(zip(log.axes, log.joint or ())):
        peak = float(np.max(np.abs(log.q[:, c]))) if j == "prismatic" and log.q.size else 0.0
        if peak > MAX_PRISMATIC_M:
            out.append(f"{source}: the position of A{a} (prismatic) reaches {peak:.6g} m, beyond {MAX_PRISMATIC_M:g} "
                       "m (longer than a linear track): wrong --q-scale, or millimetres as metres?")
            click.echo(f"kukaid: warning: load: {out[-1]}", err=True)
    return out
