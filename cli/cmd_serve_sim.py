"""kukaid serve-sim: a virtual KR C4 speaking KUKAVARPROXY (loopback by default)."""
from __future__ import annotations

from pathlib import Path

import click

from kukaid_cli._util import AxisNumber, FloatRange


@click.command("serve-sim")
@click.option("--host", default="127.0.0.1", show_default=True,
              help="Interface to listen on (loopback by default; 0.0.0.0 exposes it to the network).")
@click.option("--port", type=click.IntRange(0, 65535), default=7000, show_default=True,
              help="TCP port (0 picks a free one; the port is printed on stderr).")
@click.option("--axis", type=AxisNumber(1, 6), default=3, show_default=True, help="Simulated axis.")
@click.option("--trajectory", "traj_path", type=click.Path(dir_okay=False, exists=True, path_type=Path),
              help="Trajectory JSON the virtual robot runs from the start (like its KRL program); "
                   "without it the axis holds still and follows writes of the global KID_TGT (deg).")
@click.option("--robot", help="Simulate every axis of this robot (bundled name, e.g. kr6-r700-sixx, or URDF), standing "
                             "still; a --trajectory of several axes (`kukaid excite fourier`) brings its own robot.")
@click.option("--seed", type=click.IntRange(0, 2**32 - 1), default=0, show_default=True)
@click.option("--sim-config", type=click.Path(dir_okay=False, exists=True, path_type=Path),
              help="JSON overrides of the simulator's truth and settings.")
@click.option("--noise", type=float, help="Torque noise sigma, N·m.")
@click.option("--plant-friction", type=click.Choice(["gms", "lugre"]),
              help="Friction law of the simulated axis [gms: Maxwell-slip at rest, Stribeck sliding; lugre: LuGre].")
@click.option("--duration", type=FloatRange(0.0, 7 * 86400.0, min_open=True),
              help="Stop after this many seconds (default: until Ctrl-C/SIGTERM).")
@click.option("--speed", type=FloatRange(0.01, 100.0), default=1.0, show_default=True,
              help="Simulated seconds per second.")
@click.option("--ring-axes", type=click.IntRange(1, 6), multiple=True,
              help="Axes recorded by the emulated KRL ring-buffer logger (default: the simulated axis; "
                   "of one axis, only it; with --robot, any of the robot's).")
@click.option("--truth", "truth_path", type=click.Path(dir_okay=False, path_type=Path),
              help="Write every 12 ms sample the simulator took (ground truth, sim time) to this HDF5 log on exit.")
@click.option("--force", is_flag=True, help="Replace an existing --truth log.")
@click.option("--delay", type=FloatRange(0.0, 10.0), default=0.0, help="Fault injection: seconds added to every reply.")
@click.option("--q0", type=FloatRange(-360.0, 360.0, what="a position in degrees"),
              help="Start position of the axis, degrees (without --trajectory), within the simulated axis's range of "
                   "motion (A3 of a KR 6 R700 sixx: -120 to 156) [0].")
@click.option("--follower", "follower_window", nargs=2, type=float, metavar="QMIN QMAX",
              help="Emulate the program of `kukaid krl-follower` with this window (degrees): KID_TGT is "
                   "followed while KID_RUN is TRUE, clamped, and motion stops when KID_HB goes stale.")
@click.option("--stale-ms", type=int, default=200, show_default=True, help="--follower: heartbeat timeout, ms.")
@click.option("--operator", type=click.Choice(["human", "push", "pull"]),
              help="A simulated person on the link (external torque, drawn from --seed), as for run-admittance: "
                   "human (an arm that guides the link to a target and lets go there), push or pull (open loop).")
@click.option("--grip", type=click.Choice(["soft", "ordinary", "firm"]),
              help="--operator human: the person's grip [drawn from --seed].")
@click.option("--operator-start", type=FloatRange(0.0, 86400.0), default=3.0, show_default=True,
              help="--operator: seconds after the start when the hand begins; with --follower, seconds after "
                   "the run begins (KID_RUN TRUE), so the hand does not depend on when the client connects.")
def command(host: str, port: int, axis: int, traj_path: Path | None, robot: str | None, seed: int, sim_config: Path | None,
            noise: float | None, plant_friction: str | None, duration: float | None, speed: float, ring_axes: tuple[int, ...],
            truth_path: Path | None, force: bool, delay: float, q0: float | None, follower_window: tuple[float, float] | None,
            stale_ms: int, operator: str | None, operator_start: float, grip: str | None) -> None:
    """Serve the virtual KR C4's live variables over KUKAVARPROXY until interrupted.

    With --robot or a trajectory of several axes every axis of the robot is simulated
    (E6AXIS with all axes, $TORQUE_AXIS_ACT[1..6]).

    Variables: $AXIS_ACT_MEAS, $AXIS_ACT, $TORQUE_AXIS_ACT[i], $MOT_TEMP[i] (K), $OV_PRO,
    $ROB_TIMER, PING, global variables (KID_TGT commands the axis), and the KRL ring-buffer
    logger's KID_* globals (see `kukaid krl-logger`).
    """
    import math

    from kukaid.atomic import check_writable
    from kukaid.krc.krl_logger import RingLayout
    from kukaid.sim import SimConfig, VirtualKRC4, load_sim_config
    from kukaid.krc.sim_source import SimSource
    from kukaid_cli._util import (check_noise, check_outputs, check_suffix, config_axis, given, refuse_overwrite,
                                  usage_errors)

    if grip is not None and operator != "human":
        raise click.UsageError("--grip is for --operator human")
    if operator is None and given("operator_start"):
        raise click.UsageError("--operator-start is for --operator (a simulated person)")
    if not follower_window and given("stale_ms"):
        raise click.UsageError("--stale-ms is for --follower")
    if follower_window and traj_path is not None:  # a KRC runs one program: the follower or the trajectory's
        raise click.UsageError("--follower emulates the program of `kukaid krl-follower`, --trajectory another program "
                               "the virtual robot runs: not with --trajectory (the follower's axis stands until "
                               "KID_TGT moves it)")
    if truth_path is not None:  # checked now, not after the session
        check_suffix(truth_path, ".h5", ".hdf5")
        check_outputs([truth_path], [traj_path, sim_config])
        refuse_overwrite(truth_path, force)
        check_writable(truth_path)
    traj = None
    if traj_path is not None:
        from kukaid.capture import check_limits
        from kukaid.excite.fourier import load_trajectory

        traj = load_trajectory(traj_path)
        check_limits(traj, where=str(traj_path))
    if plant_friction is not None and (robot is not None or hasattr(traj, "axes")):
        raise click.UsageError("--plant-friction is for the one-axis simulator (not with --robot or a robot trajectory)")
    if robot is not None or hasattr(traj, "axes"):
        _serve_robot(host, port, traj, robot, seed, sim_config, duration, speed, ring_axes, truth_path, delay,
                     dict(axis=axis if given("axis") else None,
                          noise=noise, q0=q0, follower=follower_window, operator=operator))
        return
    cfg = load_sim_config(sim_config) if sim_config else SimConfig()
    if plant_friction is not None:
        cfg = cfg.replace(friction_law=plant_friction)
    if noise is not None:
        check_noise(noise)
        cfg = cfg.replace(noise_sigma=noise)
    if traj is not None:
        if given("axis") and int(getattr(traj, "axis", axis) or axis) != axis:
            raise click.UsageError(f"--axis {axis} differs from the trajectory's axis A{traj.axis} ({traj_path}); "
                                   "the trajectory's axis is simulated")
        axis = int(getattr(traj, "axis", axis) or axis)
    # a --sim-config's "axis" is simulated (as run-admittance does), or refused when it is not the axis asked for
    axis = config_axis(sim_config, axis if traj is not None or given("axis") else None,
                       str(traj_path) if traj is not None else f"--axis {axis}") or axis
    if q0 is not None and traj is not None:
        raise click.UsageError("--q0 is for a robot without --trajectory (it starts where the trajectory does)")
    from kukaid.capture import simulated_range

    lo, hi, text = simulated_range(axis)
    for name, values in (("--q0", () if q0 is None else (q0,)), ("--follower", follower_window or ())):
        for v in values:  # a follower's window beyond it was taken (trial 20)
            if not lo - 1e-9 <= math.radians(v) <= hi + 1e-9:
                raise click.BadParameter(f"{v:g} degrees is outside {text}", param_hint=name)
    sim = VirtualKRC4(cfg, seed=seed, axis=axis)
    if q0 is not None:
        sim.reset(math.radians(q0))
    if operator is not None:
        from kukaid.sim.operator import make_operator

        def hand_on() -> None:
            sim.set_external_torque(make_operator(operator, seed, sim.q, t_start=sim.t + operator_start, grip=grip))

        if not follower_window:
            hand_on()
    follower = None
    if follower_window:
        from kukaid.krc.krl_follower import FollowerConfig

        with usage_errors():  # the options alone
            follower = FollowerConfig(axis=axis, q_min_deg=follower_window[0], q_max_deg=follower_window[1],
                                      stale_ms=stale_ms)
    with usage_errors("--ring-axes"):  # the options alone
        ring = RingLayout(axes=tuple(ring_axes) or (axis,))
    other = [a for a in ring.axes if a != axis]
    if other:  # the emulated logger would record a standing axis with no torque at all
        raise click.BadParameter(f"A{other[0]} is not simulated: the one-axis simulator runs A{axis} only (--robot "
                                 "runs every axis)", param_hint="--ring-axes")
    source = SimSource(sim, axis=axis, trajectory=traj, speed=speed, ring=ring, follower=follower,
                       on_run=hand_on if operator is not None and follower else None).start()
    _run(source, sim, traj, host, port, duration, delay, truth_path, f"A{axis}")


def _serve_robot(host: str, port: int, traj, robot: str | None, seed: int, sim_config: Path | None,
                 duration: float | None, speed: float, ring_axes: tuple[int, ...], truth_path: Path | None,
                 delay: float, one_axis: dict) -> None:
    """serve-sim with every axis of a robot: the six-axis virtual KR C4."""
    from kukaid.capture import robot_sim_config
    from kukaid.krc.krl_logger import RingLayout
    from kukaid.krc.sim_source import SimSource
    from kukaid.sim.robot_plant import VirtualRobotKRC4

    given = [k for k, v in one_axis.items() if v is not None and v != ()]
    if given:
        raise click.UsageError(f"option --{given[0].replace('_', '-')} is for a one-axis simulator (not with --robot "
                               f"or a trajectory of several axes)")
    if traj is not None and not hasattr(traj, "axes"):
        raise click.UsageError("--robot needs a trajectory of all its axes (`kukaid excite fourier`), or none")
    name = robot or traj.robot
    if traj is not None and robot is not None and traj.robot and robot != traj.robot:
        raise click.UsageError(f"--robot {robot} differs from the trajectory's robot {traj.robot}")
    sim = VirtualRobotKRC4(robot_sim_config(sim_config, name), seed=seed)
    ring = RingLayout(axes=tuple(ring_axes) or tuple(a for a in sim.axes if a <= 6))
    source = SimSource(sim, trajectory=traj, speed=speed, ring=ring).start()
    _run(source, sim, traj, host, port, duration, delay, truth_path, f"A1..A{sim.n}")


def _run(source, sim, traj, host: str, port: int, duration: float | None, delay: float, truth_path: Path | None,
         label: str) -> None:
    """Serve ``source`` until the duration ends or a signal; write the ground truth."""
    import signal
    import threading

    from kukaid.errors import KukaidError
    from kukaid.krc.server import Faults, KvpServer

    stop = threading.Event()
    old = signal.signal(signal.SIGTERM, lambda *_: stop.set())
    try:
        server = KvpServer(source, host=host, port=port, faults=Faults(delay=delay)).start()
        click.echo(f"serve-sim: virtual KR C4 ({label}) listening on {host}:{server.port}", err=True)
        try:
            stop.wait(duration) if duration is not None else _wait_forever(stop)
        except KeyboardInterrupt:
            pass
        finally:
            server.stop()
    finally:
        source.stop()
        signal.signal(signal.SIGTERM, old)
    if source.error is not None:
        raise KukaidError(f"serve-sim: the simulation stopped: {source.error}")
    if truth_path is not None:
        _write_truth(source, sim, traj, truth_path)
        click.echo(f"serve-sim: ground truth written to {truth_path}", err=True)


def _wait_forever(stop) -> None:
    while not stop.wait(0.5):
        pass


def _write_truth(source, sim, traj, path: Path) -> None:
    from kukaid.logs import AxisLog, write_hdf5

    d = source.truth()
    attrs = dict(sim.log_attrs(traj)) if hasattr(sim, "log_attrs") else {}
    attrs.update(source="virtual-krc4 (serve-sim ground truth)", time_base="simulated time, s")
    log = AxisLog(time=d["time"], q=d["q"], tau=d["tau"], axes=source.axes, q_cmd=d.get("q_cmd"),
                  temp=d.get("temp"), tau_ext_true=d.get("tau_ext_true"), attrs=attrs)
    write_hdf5(log, path)
