"""kukaid excite: excitation trajectories of the paper's experiments (JSON) and KRL programs."""
from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import click

from kukaid_cli._util import JSON_HELP, AxisNumber

KINDS = ("friction", "inertia", "presliding", "validation", "fourier")
_ONE_AXIS = KINDS[:4]


def _floats(text: str) -> list[float]:
    try:
        return [float(x) for x in text.replace(" ", "").split(",") if x]
    except ValueError:
        raise click.BadParameter(f"'{text}' is not a comma-separated list of numbers") from None


#: a Fourier excitation whose base regressor is worse conditioned than this is written with a warning
#: (optimised ones reach about 90 on the bundled KR 6; the standard deviations scale with it)
COND_WARN = 1000.0


def _seconds(v: float) -> float:
    """A duration option: at most an hour (the generators build whole arrays at the IPO rate)."""
    if v != v:
        raise click.BadParameter(f"{v} is not a number of seconds")
    if not v <= 3600.0:
        raise click.BadParameter(f"{v} s is longer than an hour")
    return float(v)


# option -> (generator parameter, conversion, kinds it applies to); None kinds = all
_DEG = 3.141592653589793 / 180.0


def _centre(v: float) -> float:
    """--centre-deg in rad: a position (nan or inf was said as a friction window too short for --v-max, or as the
    trajectory's "'q' is not a finite number at index 0")."""
    if v != v or v in (float("inf"), float("-inf")):
        raise click.BadParameter(f"{v} is not a position in degrees")
    return v * _DEG

_OPTS: dict[str, tuple[str, Any, tuple[str, ...] | None]] = {
    "centre_deg": ("centre", _centre, _ONE_AXIS),
    "lead": ("lead", _seconds, _ONE_AXIS),
    "speeds": ("speeds", _floats, ("friction",)),
    "v_min": ("v_min", float, ("friction",)),
    "v_max": ("v_max", float, ("friction",)),
    "n_speeds": ("n_speeds", int, ("friction",)),
    "span_deg": ("span", lambda v: v * _DEG, ("friction",)),
    "plateau": ("plateau", _seconds, ("friction",)),
    "settle": ("settle", _seconds, ("friction",)),
    "acc": ("acc", float, ("friction", "validation")),
    "cycles": ("cycles", int, ("friction",)),
    "reposition_speed": ("reposition_speed", float, ("friction",)),
    "period": ("period", _seconds, ("inertia", "fourier")),
    "n_periods": ("n_periods", int, ("inertia",)),
    "amplitude_deg": ("amplitude", lambda v: v * _DEG, ("inertia", "validation")),
    "ramp_periods": ("ramp_periods", float, ("inertia",)),
    "tail": ("tail", _seconds, ("inertia",)),
    "step_deg": ("step", lambda v: v * _DEG, ("presliding",)),
    "step_time": ("step_time", _seconds, ("presliding",)),
    "hold": ("hold", _seconds, ("presliding",)),
    "reversals_deg": ("reversals", lambda v: [x * _DEG for x in _floats(v)], ("presliding",)),
    "reversal_time": ("reversal_time", _seconds, ("presliding",)),
    "dwell": ("dwell", _seconds, ("presliding", "validation")),
    "final_hold": ("final_hold", _seconds, ("presliding",)),
    "direction": ("direction", int, ("presliding",)),
    "periods": ("periods", _floats, ("validation",)),
    "weights": ("weights", _floats, ("validation",)),
    "sine_time": ("sine_time", _seconds, ("validation",)),
    "ramp": ("ramp", _seconds, ("validation",)),
    "moves_deg": ("moves", lambda v: [x * _DEG for x in _floats(v)], ("validation",)),
    "move_speeds": ("move_speeds", _floats, ("validation",)),
    "robot": ("robot", str, ("fourier",)),
    "harmonics": ("harmonics", int, ("fourier",)),
    "repeat": ("periods", int, ("fourier",)),
    "margin": ("margin", float, ("fourier",)),
    "span": ("span", float, ("fourier",)),
    "iterations": ("iterations", int, ("fourier",)),
    "seed": ("seed", int, ("fourier",)),
    "centres_deg": ("centre", lambda v: [x * _DEG for x in _floats(v)], ("fourier",)),
}


@click.command("excite")
@click.argument("kind", type=click.Choice(KINDS))
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="Trajectory file to write (JSON, schema kukaid.trajectory/1); an existing trajectory file is "
                   "replaced (it is derived from the options), any other file only with --force.")
@click.option("--krl", "krl_dir", type=click.Path(file_okay=False, path_type=Path),
              help="Also write a KRL program (<name>.src + <name>.dat) into this folder; existing program files "
                   "only with --force (they may have been edited for the robot).")
@click.option("--krl-name", help="KRL module name (default kukaid_<kind>); with --krl.")
@click.option("--krl-tol", type=float,
              help="Largest deviation of the KRL via-point path from the trajectory, degrees, > 0 "
                   "[0.005; fourier 0.05]; with --krl.")
@click.option("--force", is_flag=True, help="Replace an existing file of another kind (-o) or KRL program files.")
@click.option("--json", "as_json", is_flag=True, help=JSON_HELP)
@click.option("--axis", type=AxisNumber(1, 6), default=3, show_default=True, help="Axis (KUKA numbering).")
# limits
@click.option("--limits", "limits_file", type=click.Path(dir_okay=False, path_type=Path),
              help="JSON with axis limits (q_min, q_max rad; qd_max rad/s; qdd_max rad/s^2; or *_deg).")
@click.option("--q-min-deg", type=float, help="Lower position limit, deg [the KR 6 R700 sixx's for --axis; A3: -120, A2: -190].")
@click.option("--q-max-deg", type=float, help="Upper position limit, deg [A3: +156, A2: +45].")
@click.option("--qd-max-deg", type=float, help="Velocity limit, deg/s [A3: 360].")
@click.option("--qdd-max-deg", type=float, help="Acceleration limit, deg/s^2 [assumed 573 = 10 rad/s^2].")
# all kinds
@click.option("--centre-deg", type=float, help="Centre of the motion, deg [middle of the axis range; A3: 18, A2: -72.5].")
@click.option("--lead", type=float, help="Standstill at the start, s [1].")
# friction
@click.option("--speeds", help="friction: plateau speeds, rad/s, comma-separated [log-spaced v-min..v-max].")
@click.option("--v-min", type=float, help="friction: slowest speed, rad/s [0.01].")
@click.option("--v-max", type=float, help="friction: fastest speed, rad/s [1.0].")
@click.option("--n-speeds", type=int, help="friction: number of speeds [10].")
@click.option("--span-deg", type=float, help="friction: widest position window, deg [90].")
@click.option("--plateau", type=float, help="friction: wanted plateau duration, s [4].")
@click.option("--settle", type=float, help="friction: standstill after each move, s [1].")
@click.option("--acc", type=float, help="friction/validation: ramp peak acceleration, rad/s^2 [3].")
@click.option("--cycles", type=int, help="friction: back-and-forth moves per speed [1].")
@click.option("--reposition-speed", type=float, help="friction: speed between windows, rad/s [0.3].")
# inertia
@click.option("--period", type=float, help="inertia: sine period, s [4].")
@click.option("--n-periods", type=int, help="inertia: full-amplitude periods, >= 3 [3].")
@click.option("--amplitude-deg", type=float, help="inertia/validation: amplitude, deg [inertia 45.8, validation 34.4].")
@click.option("--ramp-periods", type=float, help="inertia: ramp in/out, periods [1].")
@click.option("--tail", type=float, help="inertia: standstill at the end, s [1].")
# presliding
@click.option("--step-deg", type=float, help="presliding: initiation move, deg [1].")
@click.option("--step-time", type=float, help="presliding: duration of the initiation move, s [1].")
@click.option("--hold", type=float, help="presliding: standstill after the initiation move, s [5].")
@click.option("--reversals-deg", help="presliding: reversal amplitudes, deg, comma-separated "
                                       "[0.03,0.015,0.0075,0.00375]; empty string for none.")
@click.option("--reversal-time", type=float, help="presliding: duration of each reversal, s [2].")
@click.option("--dwell", type=float, help="presliding/validation: standstill after each reversal/move, s [1 / 1.5].")
@click.option("--final-hold", type=float, help="presliding: standstill at the end, s [5].")
@click.option("--direction", type=click.Choice(["1", "-1"]), help="presliding: direction of the initiation move [1].")
# validation
@click.option("--periods", help="validation: multi-sine periods, s, comma-separated [6,2.9,1.3].")
@click.option("--weights", help="validation: relative amplitudes of the sines [0.6,0.3,0.1; equal with --periods].")
@click.option("--sine-time", type=float, help="validation: multi-sine duration, s [18].")
@click.option("--ramp", type=float, help="validation: multi-sine ramp in/out, s [3].")
@click.option("--moves-deg", help="validation: move targets relative to the centre, deg, comma-separated "
                                  "(with --move-speeds).")
@click.option("--move-speeds", help="validation: cruise speed of each move, rad/s, comma-separated.")
# fourier
@click.option("--robot", help="fourier: bundled robot (kr6-r700-sixx) or URDF file [kr6-r700-sixx].")
@click.option("--harmonics", type=int, help="fourier: harmonics per joint [5].")
@click.option("--repeat", type=int, help="fourier: number of periods [3] (--period: the period, s [10]).")
@click.option("--margin", type=float, help="fourier: fraction of the velocity/acceleration limits used [0.9].")
@click.option("--span", type=float, help="fourier: fraction of each joint's range used around its centre [0.6].")
@click.option("--iterations", type=int, help="fourier: optimiser iterations (L-BFGS-B) [10].")
@click.option("--seed", type=click.IntRange(0, 2**32 - 1), help="fourier: seed of the optimiser's random starts [0].")
@click.option("--centres-deg", help="fourier: centre of each joint's motion, deg, comma-separated [middle of the ranges].")
def command(kind: str, output: Path, krl_dir: Path | None, krl_name: str | None, krl_tol: float | None,
            force: bool, as_json: bool, axis: int, limits_file: Path | None, q_min_deg: float | None, q_max_deg: float | None,
            qd_max_deg: float | None, qdd_max_deg: float | None, **opts: Any) -> None:
    """Write the trajectory of experiment KIND (friction, inertia, presliding, validation, fourier).

    The trajectory is the commanded position of the axis at the KR C4's 12 ms IPO rate.  It is
    refused, with nothing written, if it breaks the axis's position, velocity or acceleration
    limit (A3 of a KR 6 R700 sixx unless overridden).  `fourier` moves every axis of --robot
    together (limits from the URDF; --limits JSON {"A1": {...}, ...} overrides them, --qdd-max-deg
    sets every axis's acceleration limit).  Defaults in [brackets].
    """
    from kukaid.excite import AxisLimits, generate
    from kukaid.atomic import write_texts_atomic
    from kukaid.errors import LimitError, TrajectoryError
    from kukaid.excite.fourier import ROBOT_SCHEMA
    from kukaid.excite.trajectory import SCHEMA
    from kukaid.krc.krl import check_krl_name
    from kukaid_cli._util import (check_outputs, check_suffix, echo_json, krl_texts, refuse_other_kind,
                                  require_positive, usage_errors)

    check_suffix(output, ".json")
    check_outputs([output], [limits_file])
    for flag, v in (("--krl-name", krl_name), ("--krl-tol", krl_tol)):
        if v is not None and krl_dir is None:
            raise click.UsageError(f"option {flag} needs --krl DIR (it applies to the KRL program)")
    require_positive(("--krl-tol", krl_tol))
    if krl_name is not None:
        with usage_errors("--krl-name"):
            check_krl_name(krl_name)
    kwargs = _generator_options(kind, opts)
    if "moves" in kwargs and "move_speeds" not in kwargs:  # the default speeds are of the default moves
        raise click.UsageError(f"--moves-deg gives {len(kwargs['moves'])} move(s): give --move-speeds too, one cruise "
                               "speed (rad/s) per move")
    refuse_other_kind(output, force, ROBOT_SCHEMA if kind == "fourier" else SCHEMA)  # after the options: said first
    if kind == "fourier":
        _fourier(output, krl_dir, krl_name, krl_tol, force, limits_file, q_min_deg, q_max_deg, qd_max_deg,
                 qdd_max_deg, kwargs, as_json)
        return
    limits = AxisLimits.kr6_r700_sixx(axis)
    if limits_file is not None:
        limits = AxisLimits.load(limits_file, base=limits)
    over = {k: v for k, v in (("q_min_deg", q_min_deg), ("q_max_deg", q_max_deg), ("qd_max_deg", qd_max_deg),
                              ("qdd_max_deg", qdd_max_deg)) if v is not None}
    if over:
        with usage_errors():
            limits = AxisLimits.from_dict(over, base=limits, where="limit options")
    with usage_errors(types=(TrajectoryError,)):  # a generator option out of range (a broken limit stays 1)
        try:
            traj = generate(kind, axis=axis, limits=limits, **kwargs)
        except LimitError as e:  # a broken limit stays exit 1; a position limit says what sets the motion's size
            raise LimitError(f"{e}; the motion's size is {_POSITION_HINT[kind]}, its place --centre-deg"
                             if "position limit" in str(e)
                             and kind in _POSITION_HINT else str(e)) from None
        except TrajectoryError as e:  # the generator names its parameter: say which option it is
            raise TrajectoryError(_option_names(str(e))) from None
    files = {output: traj.json_text()}
    msg = f"{output}: {kind} trajectory of A{axis}, {traj.n_samples} samples, {traj.duration:.2f} s"
    figures = {"output": str(output), "kind": kind, "axes": [axis], "samples": traj.n_samples,
               "duration": traj.duration, "krl": None}
    if krl_dir is not None:
        from kukaid.krc.krl import krl_program

        src, dat, summary = krl_program(traj, name=krl_name, limits=limits,
                                        tol_deg=0.005 if krl_tol is None else krl_tol)
        files.update(krl_texts(krl_dir, {f"{summary['name']}.src": src, f"{summary['name']}.dat": dat}, force))
        msg += f"; KRL {krl_dir / summary['name']}.src/.dat, {summary['points']} via points"
        figures["krl"] = _krl_figures(krl_dir, summary)
    check_outputs(files, [limits_file])
    write_texts_atomic(files)  # all or nothing
    if as_json:
        echo_json(figures)
    click.echo(msg, err=True)
    if krl_dir is not None:
        _krl_speed_warning(summary, limits.qd_max)


#: what sets the size of each kind's motion (a position limit it breaks names them)
_POSITION_HINT = {"friction": "--span-deg [90]", "inertia": "--amplitude-deg [45.8]",
                  "validation": "--amplitude-deg [34.4] and --moves-deg", "presliding": "--step-deg [1] and --reversals-deg [0.03,...]"}


def _krl_figures(krl_dir: Path, summary: dict) -> dict:
    return {"src": str(krl_dir / f"{summary['name']}.src"), "dat": str(krl_dir / f"{summary['name']}.dat"),
            "via_points": summary["points"], "max_speed_error": summary.get("max_speed_error")}


#: a KRL program whose pieces of 0.5 s or more run this far off their speed is said so on stderr
KRL_SPEED_WARN = 0.05


def _krl_speed_warning(summary: dict, qd_max: float) -> None:
    """The KRL's largest speed error of a piece of 0.5 s or more (in the .dat's header only, before);
    ``qd_max`` the axis's speed limit, rad/s."""
    err = summary.get("max_speed_error")
    if err is not None and err > KRL_SPEED_WARN:
        click.echo(f"kukaid: warning: excite: the KRL program runs a piece of 0.5 s or more {100 * err:.0f} % off "
                   "its speed: $VEL_AXIS and $OV_PRO are whole percentages, and a speed below 0.01 % of the maximum "
                   f"cannot be programmed (it runs at that, {1e-4 * qd_max / _DEG:.3g} deg/s); the captured log records "
                   "what the robot did", err=True)


def _option_names(msg: str) -> str:
    """A generator's message "option span: ..." with the command's option ("option --span-deg: ...")
    for the parameters the options set (one option may set parameters of several kinds); the value
    a degree option's message quotes (``got 0.0175``, radians to the generator) in degrees, as typed."""
    flags: dict[str, str] = {}
    for name, (param, _, _) in _OPTS.items():
        flags.setdefault(param, "--" + name.replace("_", "-"))
    subject = re.match(r"option (\w+):", msg)
    if subject and flags.get(subject.group(1), "").endswith("-deg"):
        msg = re.sub(r"got (\S+)$", lambda m: f"got {_degrees(m.group(1))}", msg)
    return re.sub(r"option (\w+)", lambda m: f"option {flags.get(m.group(1), m.group(1))}", msg)


def _degrees(rad: str) -> str:
    try:
        return f"{float(rad) / _DEG:g} deg"
    except ValueError:
        return rad


def _generator_options(kind: str, opts: dict[str, Any]) -> dict[str, Any]:
    """The generator's keyword arguments from the options given; an option of another kind is refused."""
    kwargs: dict[str, Any] = {}
    for name, value in opts.items():
        if value is None:
            continue
        param, conv, kinds = _OPTS[name]
        flag = "--" + name.replace("_", "-")
        if kinds is not None and kind not in kinds:
            raise click.UsageError(f"option {flag} does not apply to '{kind}' (it is for {', '.join(kinds)})")
        try:
            kwargs[param] = conv(value)
        except click.BadParameter as e:
            raise click.BadParameter(e.message, param_hint=flag) from None
    if kind == "validation" and "periods" in kwargs and "weights" not in kwargs:
        kwargs["weights"] = [1.0] * len(kwargs["periods"])  # the default weights are for the default periods
    return kwargs


def _fourier(output: Path, krl_dir: Path | None, krl_name: str | None, krl_tol: float | None, force: bool,
             limits_file: Path | None,
             q_min_deg: float | None, q_max_deg: float | None, qd_max_deg: float | None, qdd_max_deg: float | None,
             kwargs: dict[str, Any], as_json: bool) -> None:
    """`kukaid excite fourier`: every axis of the robot, limits from its URDF."""
    from kukaid.atomic import write_texts_atomic
    from kukaid.errors import TrajectoryError
    from kukaid.excite.fourier import fourier, robot_limits
    from kukaid.jsonfile import read_json
    from kukaid.models.limits import AxisLimits
    from kukaid.models.urdf import load_model
    from kukaid_cli._util import check_outputs, echo_json, given, krl_texts, progress, require_positive, usage_errors

    require_positive(("--qdd-max-deg", qdd_max_deg))
    if given("axis"):
        raise click.UsageError("option --axis does not apply to 'fourier' (it moves every axis of --robot)")
    for flag, v in (("--q-min-deg", q_min_deg), ("--q-max-deg", q_max_deg), ("--qd-max-deg", qd_max_deg)):
        if v is not None:
            raise click.UsageError(f"option {flag} does not apply to 'fourier' (give per-axis limits with --limits)")
    robot = kwargs.pop("robot", "kr6-r700-sixx")
    model = load_model(robot)
    if krl_dir is not None and model.nv > 6:  # before the optimiser's minute, not after it
        raise TrajectoryError(f"{robot}: --krl writes a KR C4 program, which moves A1..A6; this robot has "
                              f"{model.nv} joints (A1..A{model.nv}): write the trajectory without --krl")
    limits = robot_limits(model, None if qdd_max_deg is None else qdd_max_deg * _DEG, robot=robot)
    if limits_file is not None:
        over = read_json(limits_file, TrajectoryError, "limits file (JSON)", schemas=())
        known = {lim.name for lim in limits}
        if not isinstance(over, dict) or any(k not in known for k in over):
            raise TrajectoryError(f"{limits_file}: expected an object {{axis name: limits}} with axis names among "
                                  f"{', '.join(sorted(known))}")
        limits = [AxisLimits.from_dict(over[lim.name], base=lim, where=f"{limits_file}: {lim.name}")
                  if lim.name in over else lim for lim in limits]
    with usage_errors(types=(TrajectoryError,)), progress(1.0, "excite fourier") as update:
        traj = fourier(robot=robot, limits=limits, model=model, progress=update, **kwargs)
    files = {output: traj.json_text()}
    msg = (f"{output}: fourier trajectory of {len(traj.axes)} axes, {traj.n_samples} samples, {traj.duration:.2f} s, "
           f"regressor condition number {traj.params['cond']:.4g}")
    figures = {"output": str(output), "kind": "fourier", "robot": traj.robot, "axes": list(traj.axes),
               "samples": traj.n_samples, "duration": traj.duration, "condition_number": traj.params["cond"],
               "krl": None}
    if krl_dir is not None:
        from kukaid.krc.krl import krl_program_robot

        src, dat, summary = krl_program_robot(traj, name=krl_name, tol_deg=0.05 if krl_tol is None else krl_tol)
        files.update(krl_texts(krl_dir, {f"{summary['name']}.src": src, f"{summary['name']}.dat": dat}, force))
        msg += f"; KRL {krl_dir / summary['name']}.src/.dat, {summary['points']} via points"
        figures["krl"] = _krl_figures(krl_dir, summary)
    check_outputs(files, [limits_file])
    write_texts_atomic(files)
    if as_json:
        echo_json(figures)
    click.echo(msg, err=True)
    if traj.params["cond"] > COND_WARN:
        click.echo(f"kukaid: warning: excite: regressor condition number {traj.params['cond']:.3g} (above {COND_WARN:g}): the base "
                   "parameters' standard deviations grow with it, some will be poorly determined; widen the limits "
                   "(--qdd-max-deg, --limits), add harmonics or iterations", err=True)
