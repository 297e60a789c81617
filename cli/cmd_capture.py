"""kukaid capture: run a trajectory on the virtual KR C4 (or record a real one) into an axis log."""
from __future__ import annotations

import math
from pathlib import Path

import click

from kukaid_cli._util import AXIS, JSON_HELP, PORT, FloatRange

from kukaid_cli._util import progress as progress_bar


@click.command("capture")
@click.argument("trajectory", required=False, type=click.Path(dir_okay=False, path_type=Path))
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="Axis log to write (HDF5), written incrementally.")
@click.option("--backend", type=click.Choice(["sim", "kvp"]), default="sim", show_default=True,
              help="sim: the virtual KR C4; kvp: a KR C4 over KUKAVARPROXY.")
@click.option("--force", is_flag=True, help="Replace an existing log.")
@click.option("--json", "as_json", is_flag=True, help=JSON_HELP)
# sim
@click.option("--seed", type=click.IntRange(0, 2**32 - 1), default=0, show_default=True,
              help="sim: seed of noise, vibration and effects.")
@click.option("--sim-config", type=click.Path(dir_okay=False, path_type=Path),
              help="sim: JSON overriding the simulator's truth and settings (a one-axis trajectory's axis "
                   "has the paper's A3 dynamics, Izz 2.28 kg·m², Mx 18.5 N·m, whatever its number: for another "
                   "axis's gravity give its Izz and Mx here).")
@click.option("--noise", type=float, help="sim: torque noise sigma, N·m [0.5].")
@click.option("--effect", "effects", multiple=True, metavar="NAME[=SIZE]",
              help="sim: hide an effect (gravity_sine, torque_offset, position_ripple, thermal_drift, "
                   "load_dependent_friction, backlash) of SIZE N·m [drawn: 2 to 5 times the noise sigma]; "
                   "other parameters drawn from the seed; repeatable.")
@click.option("--chunk", type=FloatRange(0.1, 60.0), default=1.5, show_default=True,
              help="sim: simulated seconds per block written to the log.")
@click.option("--settle", type=FloatRange(0.0, 60.0), default=0.5, show_default=True,
              help="sim: seconds recorded after the trajectory ends.")
# kvp
@click.option("--host", default="127.0.0.1", show_default=True, help="kvp: KUKAVARPROXY host.")
@PORT
@click.option("--axis", "axes", type=AXIS, multiple=True, help="kvp: axis to record; repeatable [3; with TRAJECTORY, the axes it moves].")
@click.option("--duration", type=FloatRange(0.0, 7 * 86400.0, min_open=True),
              help="kvp: seconds to record (Ctrl-C before then: an interrupted capture).")
@click.option("--until-interrupt", is_flag=True, help="kvp: record until Ctrl-C / SIGTERM (not with --duration).")
@click.option("--mode", type=click.Choice(["poll", "ring"]), default="poll", show_default=True,
              help="kvp: poll variables, or read kukaid's KRL ring-buffer logger.")
def command(trajectory: Path | None, output: Path, backend: str, force: bool, as_json: bool, seed: int, sim_config: Path | None,
            noise: float | None, effects: tuple[str, ...], chunk: float, settle: float, host: str, port: int,
            axes: tuple[int, ...], duration: float | None, until_interrupt: bool, mode: str) -> None:
    """Run TRAJECTORY (from `kukaid excite`) on a backend and record an axis log.

    The log is written as it is recorded: an interrupted capture (Ctrl-C, SIGTERM, a killed
    process) leaves a readable log of what was recorded.  Cut short by Ctrl-C or SIGTERM (before
    the trajectory's end, or --duration), it keeps the log, says how far it got and exits with
    status 130.  An existing log is never replaced without --force.  With --backend kvp the robot
    runs its own program (e.g. the KRL from `kukaid excite --krl`) and capture only records.
    """
    import signal

    from kukaid.capture import KvpCapture, SimCapture, capture, check_limits, check_simulated_range
    from kukaid.errors import KukaidError
    from kukaid_cli._util import check_outputs, given

    check_outputs([output], [trajectory, sim_config])  # capture() checks its suffix and --force
    if backend == "sim":
        if trajectory is None:
            raise click.UsageError("the sim backend needs a TRAJECTORY file (from `kukaid excite`)")
        given = [n for n, v in (("--host", host != "127.0.0.1"), ("--port", port != 7000), ("--axis", axes),
                                ("--duration", duration is not None), ("--until-interrupt", until_interrupt),
                                ("--mode", mode != "poll")) if v]
        if given:
            raise click.UsageError(f"option {given[0]} is for --backend kvp")
        from kukaid.excite.fourier import load_trajectory

        traj = load_trajectory(trajectory)
        check_limits(traj, where=str(trajectory))
        check_simulated_range(traj, where=str(trajectory))
        if hasattr(traj, "axes"):  # all axes of a robot (kukaid excite fourier): the six-axis virtual KR C4
            from kukaid.capture import robot_sim_config

            if noise is not None or effects:
                raise click.UsageError("options --noise and --effect are for one-axis trajectories; set the robot "
                                       "simulator's noise_rel in --sim-config")
            cfg = robot_sim_config(sim_config, traj.robot)
            be = SimCapture(traj, config=cfg, seed=seed, chunk=chunk, settle=settle,
                            extra_attrs={"trajectory_file": str(trajectory)})
        else:
            be = _one_axis_backend(traj, trajectory, sim_config, noise, effects, seed, chunk, settle)
    else:
        sim_only = [n for n, v in (("--sim-config", sim_config), ("--noise", noise is not None), ("--effect", effects),
                                   *((f"--{k}", given(k)) for k in ("seed", "chunk", "settle"))) if v]
        if sim_only:
            raise click.UsageError(f"option {sim_only[0]} is for --backend sim")
        twice = sorted({a for a in axes if axes.count(a) > 1})
        if twice:
            raise click.UsageError(f"--axis {twice[0]} is given twice")
        if duration is not None and until_interrupt:
            raise click.UsageError("options --duration and --until-interrupt contradict each other: record for "
                                   "--duration S, or until Ctrl-C with --until-interrupt")
        attrs = {}
        if trajectory is not None:
            from kukaid.excite.fourier import load_trajectory

            traj = load_trajectory(trajectory)
            attrs = {"experiment": traj.kind, "trajectory": traj.params, "trajectory_file": str(trajectory)}
            # the log is of the axes the trajectory moves: the default A3 recorded a standing axis as its experiment
            moved = tuple(traj.axes) if hasattr(traj, "axes") else (traj.axis,)
            if axes and sorted(axes) != sorted(moved):
                names = ", ".join(f"A{a}" for a in moved)
                raise click.UsageError(f"option --axis {' --axis '.join(str(a) for a in axes)} does not match "
                                       f"{trajectory}: its experiment moves {names}, the axes a capture of it "
                                       "records (leave out --axis)")
            axes = axes or moved
        be = KvpCapture(host=host, port=port, axes=axes or (3,), duration=duration, until_interrupt=until_interrupt,
                        mode=mode, attrs=attrs)

    # Ctrl-C / SIGTERM end a simulated capture cleanly between blocks (a second one aborts at once);
    # the kvp backend handles these signals itself
    import threading

    stop = threading.Event()

    def _stop(signum, frame):  # pragma: no cover - exercised through a subprocess
        if stop.is_set():
            raise KeyboardInterrupt
        stop.set()

    old = {}
    if backend == "sim":
        for sig in (signal.SIGINT, signal.SIGTERM):
            old[sig] = signal.signal(sig, _stop)
    total = be.total()
    interrupted = False
    result = None
    try:
        if total is None:
            result = capture(be, output, force=force, progress=None, stop=stop if backend == "sim" else None)
        else:
            with progress_bar(total, f"capture ({backend})") as update:
                result = capture(be, output, force=force, progress=update, stop=stop if backend == "sim" else None)
        interrupted = not result.complete
    except KeyboardInterrupt:
        interrupted = True
    finally:
        for sig, h in old.items():
            signal.signal(sig, h)
    if interrupted:
        kept = ""
        if result is not None and result.n_samples == 0:  # the output, if any, is an earlier log, untouched
            kept = " before its first sample; nothing recorded" + (f" ({output} is not changed)" if output.exists()
                                                                    else "")
        elif output.exists():
            try:
                from kukaid.logs import read_hdf5

                log = read_hdf5(output)
                of = f" of {total:g}" if total else ""
                kept = f" after {log.duration:.2f}{of} s; {log.n_samples} samples kept in {output}"
            except KukaidError:
                kept = ""
        click.echo(f"kukaid: error: capture interrupted{kept}", err=True)
        raise SystemExit(130)
    if as_json:
        from kukaid_cli._util import echo_json

        echo_json({"output": str(result.output), "samples": result.n_samples, "duration": result.duration,
                   "backend": backend, "source": be.name, "seed": seed if backend == "sim" else None,
                   "complete": result.complete})
    click.echo(f"{result.output}: {result.n_samples} samples, {result.duration:.2f} s "
               f"({be.name}{', seed ' + str(seed) if backend == 'sim' else ''})", err=True)
    gaps, ovf = result.info.get("gaps") or [], int(result.info.get("ring_overflows") or 0)
    if gaps or ovf:  # samples the controller took are not in the log: said now, not first by fit's refusal
        lost = sum(float(g1) - float(g0) for g0, g1 in gaps)
        why = (f"the ring overflowed {ovf} times: the PC read it too slowly (a longer ring: kukaid krl-logger "
               "--blocks)" if ovf else "the link dropped")
        click.echo(f"kukaid: warning: capture: {len(gaps)} gap(s) in {result.output}, {lost:.3g} s without samples: "
                   f"{why}; the gaps are in its dataset 'gaps'", err=True)
    from kukaid.capture import FOLLOWING_WARN

    follow = float(result.info.get("following_error_max") or 0.0)
    if follow > FOLLOWING_WARN:  # the virtual KR C4 runs on where a real one's following-error monitor stops
        click.echo(f"kukaid: warning: capture: the axis did not follow its command, up to {math.degrees(follow):.3g} "
                   "degrees apart: the simulated drive cannot hold this trajectory (its tau_max, or a load beyond it); "
                   "a real KR C4 would stop on its following error", err=True)


def _one_axis_backend(traj, trajectory: Path, sim_config: Path | None, noise: float | None, effects: tuple[str, ...],
                      seed: int, chunk: float, settle: float):
    """The one-axis virtual KR C4 with the requested noise and hidden effects."""
    from kukaid.capture import SimCapture, parse_effect, sim_config as make_config
    from kukaid.errors import SimConfigError, TrajectoryError
    from kukaid_cli._util import check_noise, config_axis

    if traj.axis > 6:  # a trajectory file allows the external axes E1-E6 (7-12) a real controller drives
        raise TrajectoryError(f"{trajectory}: axis {traj.axis} is the external axis E{traj.axis - 6}; the virtual KR C4 "
                              "has axes 1 to 6 (record an external axis on a real controller: --backend kvp)")
    parsed = [parse_effect(e) for e in effects]
    names = [e[0] for e in parsed]
    if len(set(names)) != len(names):
        raise click.UsageError(f"--effect {next(n for n in names if names.count(n) > 1)} is given twice")
    check_noise(noise)
    if sim_config is not None:
        make_config(sim_config)  # an error in the file is one in the data (exit 1), before the options'
        config_axis(sim_config, traj.axis, str(trajectory), "excite the trajectory with --axis {said}")
    for spec, effect in zip(effects, parsed):  # a size the simulator refuses is the option's error
        try:
            make_config(sim_config, effects=[effect], seed=seed)
        except SimConfigError as e:
            raise click.BadParameter(f"{spec}: size out of the simulator's range: {str(e).split(': ', 1)[-1]}",
                                     param_hint="--effect") from None
    cfg, extra = make_config(sim_config, noise=noise, effects=parsed, seed=seed)
    extra["trajectory_file"] = str(trajectory)
    return SimCapture(traj, config=cfg, seed=seed, chunk=chunk, settle=settle, extra_attrs=extra)
