"""kukaid krl-logger: write the KRL ring-buffer logger (SUB program + globals) for exact 12 ms capture."""
from __future__ import annotations

from pathlib import Path

import click

from kukaid_cli._util import AxisNumber


@click.command("krl-logger")
@click.option("--axis", "axes", type=AxisNumber(1, 6), multiple=True, help="Axis to log (repeatable; default 3).")
@click.option("--blocks", type=click.IntRange(2, 32), default=8, show_default=True, help="Ring slots.")
@click.option("--block-samples", type=click.IntRange(1, 32), default=8, show_default=True,
              help="12 ms samples per block.")
@click.option("-o", "--output", "outdir", type=click.Path(file_okay=False, path_type=Path), required=True,
              help="Folder to write KUKAID_LOG.SUB and KUKAID_LOG.DAT into.")
@click.option("--force", is_flag=True, help="Replace existing files.")
def command(axes: tuple[int, ...], blocks: int, block_samples: int, outdir: Path, force: bool) -> None:
    """Write the SUB program that samples $AXIS_ACT_MEAS, $TORQUE_AXIS_ACT[] and $MOT_TEMP[] every
    interpolation cycle into a ring of global blocks, read by `kukaid capture --backend kvp --mode ring`.

    Capture writes only the logger's acknowledgement counter KID_RD; it never writes any other
    robot variable.
    """
    from kukaid.errors import KukaidError
    from kukaid.krc.krl_logger import RingLayout, krl_logger_files
    from kukaid_cli._util import write_krl_files

    try:  # the options alone: a usage error naming the option
        layout = RingLayout(axes=tuple(axes) or (3,), nb=blocks, bs=block_samples)
    except KukaidError as e:
        msg = str(e).removeprefix("KRL logger: ")
        hint = "--block-samples" if "samples per block" in msg else "--blocks" if "blocks" in msg else "--axis"
        raise click.BadParameter(msg, param_hint=hint) from None
    files = krl_logger_files(layout)
    write_krl_files(outdir, files, force)
    click.echo(f"{outdir}: {', '.join(files)} (axes {', '.join(f'A{a}' for a in layout.axes)}, "
               f"{layout.nb} blocks x {layout.bs} samples = {layout.nb * layout.bs * 12} ms of buffer)", err=True)
