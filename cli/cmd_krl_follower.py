"""kukaid krl-follower: write the KRL program that moves the axis to the admittance reference."""
from __future__ import annotations

import math
from pathlib import Path

import click

from kukaid_cli._util import QD_MAX_DEG, AxisNumber, FloatRange


@click.command("krl-follower")
@click.option("--axis", type=AxisNumber(1, 6), default=3, show_default=True, help="Axis the program moves.")
@click.option("--q-min", type=FloatRange(-360.0, 360.0), required=True, help="Position window, lower bound, degrees (clamped on the KRC).")
@click.option("--q-max", type=FloatRange(-360.0, 360.0), required=True, help="Position window, upper bound, degrees (clamped on the KRC).")
@click.option("--qd-max", type=float, default=QD_MAX_DEG, show_default=True,
              help="Axis speed limit, deg/s, at least 1 % of --axis-speed (the KRC's limit is the whole percentage "
                   "at or below it).")
@click.option("--axis-speed", type=float, default=360.0, show_default=True,
              help="The machine data's maximum speed of the axis, deg/s (A3 of a KR 6 R700 sixx: 360): "
                   "$VEL_AXIS = 100 qd-max / axis-speed %, rounded down to a whole percentage (an INT on the KRC).")
@click.option("--acc-pct", type=click.IntRange(1, 100), default=30, show_default=True,
              help="$ACC_AXIS of the axis, whole %.")
@click.option("--stale-ms", type=int, default=200, show_default=True,
              help="Motion stops when the PC's heartbeat KID_HB is older than this, ms.")
@click.option("-o", "--output", "outdir", type=click.Path(file_okay=False, path_type=Path), required=True,
              help="Folder to write KUKAID_FOLLOW.SRC and KUKAID_FOLLOW.DAT into.")
@click.option("--force", is_flag=True, help="Replace existing files.")
def command(axis: int, q_min: float, q_max: float, qd_max: float, axis_speed: float, acc_pct: int, stale_ms: int,
            outdir: Path, force: bool) -> None:
    """Write the KRL program that follows KID_TGT for `kukaid run-admittance --backend kvp`.

    On the controller, independent of the PC: the target is clamped to [--q-min, --q-max], the
    speed limited by $VEL_AXIS, and motion stops when the PC's heartbeat stops.  Run it in T1
    first; the KRC's own monitoring stays in force.
    """
    from kukaid.krc.krl_follower import FollowerConfig, krl_follower_files
    from kukaid_cli._util import usage_errors, write_krl_files

    if not (qd_max > 0 and axis_speed > 0 and qd_max <= axis_speed and math.isfinite(axis_speed)):
        raise click.UsageError(f"need 0 < --qd-max ({qd_max:g}) <= --axis-speed ({axis_speed:g}) deg/s, finite "
                               "numbers")
    # $VEL_AXIS is a whole percentage on the KRC: rounded down, so the controller never runs faster than --qd-max
    vel_pct = math.floor(100.0 * qd_max / axis_speed + 1e-9)
    if vel_pct < 1:
        raise click.UsageError(f"--qd-max {qd_max:g} deg/s is below 1 % of --axis-speed {axis_speed:g} deg/s, the "
                               f"slowest $VEL_AXIS (a whole percentage) the KRC takes: give at least "
                               f"{axis_speed / 100:g} deg/s")
    with usage_errors():  # the options alone
        cfg = FollowerConfig(axis=axis, q_min_deg=q_min, q_max_deg=q_max, vel_pct=vel_pct, acc_pct=acc_pct,
                             stale_ms=stale_ms)
    files = krl_follower_files(cfg)
    write_krl_files(outdir, files, force)
    vel = cfg.vel_pct * axis_speed / 100
    click.echo(f"{outdir}: {', '.join(files)} (A{axis}, window [{q_min:g}, {q_max:g}] deg, "
               f"$VEL_AXIS {cfg.vel_pct} % = {vel:g} deg/s, heartbeat {stale_ms} ms)", err=True)
    if vel < qd_max - 1e-9:  # the KRC bounds the axis below what was asked: a faster reference runs ahead of it
        click.echo(f"kukaid: warning: krl-follower: the KRC moves A{axis} no faster than {vel:g} deg/s (--qd-max {qd_max:g} rounded "
                   f"down to a whole percentage of {axis_speed:g} deg/s): give run-admittance --qd-max {vel:g} or "
                   f"less (its default is {QD_MAX_DEG:g}), or its reference runs ahead of the axis", err=True)
