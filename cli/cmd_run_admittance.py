"""kukaid run-admittance: sensorless admittance control (constant or adaptive damping)."""
from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import click

from kukaid_cli._util import AXIS, PORT, QD_MAX_DEG, URDF, FloatRange


def _fmt(v):
    if isinstance(v, float):
        return f"{v:.4g}"
    if isinstance(v, list):
        return "[" + ", ".join(_fmt(x) for x in v) + "]"
    return str(v)


#: units of the summary's figures (detection_delay < 0: Γr crossed the threshold before the true torque did)
_UNITS = {"detection_delay": " s", "residual_rmse": " N·m", "residual_rmse_dynamic": " N·m",
          "residual_rmse_quasi_static": " N·m", "mean_sq_dgamma": " N²·m²", "displacement": " rad",
          "peak_speed": " rad/s", "D_range": " N·m·s/rad", "dgamma2": " N²·m²", "dgamma2_true": " N²·m²",
          "end_error": " of the move",
          # the paper's cost ξ = ½ dΓr² + ½ λ Γr² (eq. 19; λ a pure number): a squared torque too
          "mean_cost": " N²·m²", "xi": " N²·m²", "xi_true": " N²·m²"}
#: the summary's names of figures whose JSON key does not say what was measured and what commanded
_LABELS = {"displacement": "measured displacement", "peak_speed": "reference peak speed"}


#: the longest run, s: the run log is held in memory until it is written, 3.2 MB per simulated
#: minute (--duration 60 / 600 / 1800 s: peak RSS 227 / 257 / 320 MB), so an hour takes about 0.2 GB
#: more (about 0.5 GB with --report, whose comparison run is held too: 305 MB at 600 s); a hand-guiding
#: session longer than that is several runs
MAX_DURATION = 3600.0


def _check_window(lo: float, hi: float, q0: float | None, defaulted: bool) -> None:
    """The position window and the simulated start, in the options' unit (degrees): usage errors."""
    where = "--q-min/--q-max" + ("; sim default --q0 -/+ 90" if defaulted and q0 is not None else "")
    if not lo < hi:
        raise click.UsageError(f"position window [{lo:.4g}, {hi:.4g}] degrees ({where}) must have q_min < q_max")
    if q0 is not None and not lo <= q0 <= hi:
        raise click.UsageError(f"start position --q0 {q0:.4g} degrees is outside the position window "
                               f"[{lo:.4g}, {hi:.4g}] degrees ({where})")


def _default_start(axis: int) -> float:
    """The simulated start of a KR 6 R700 sixx's ``axis`` when --q0 is not given, degrees: 30, or the middle of
    the axis's range when 30 lies within 40 degrees of an end (A2: 15 from its upper end, and a person guiding
    0.2-0.5 rad from there left the window: 199 clipped cycles, new-user trial 14)."""
    from kukaid.models.limits import AxisLimits

    r = AxisLimits.kr6_r700_sixx(axis)
    lo, hi = math.degrees(r.q_min), math.degrees(r.q_max)
    return 30.0 if lo + 40.0 <= 30.0 <= hi - 40.0 else 0.5 * (lo + hi)


def _check_start(q0: float, lo: float, hi: float, what: str) -> None:
    """The simulated start --q0 (degrees) within the simulated axis's range of motion ``lo``..``hi`` (rad;
    an infinite bound: none): the virtual robot has no hard stops, a start beyond them simulates no robot."""
    q = math.radians(q0)
    if (math.isfinite(lo) and q < lo - 1e-9) or (math.isfinite(hi) and q > hi + 1e-9):
        raise click.BadParameter(f"{q0:g} degrees is outside the range of motion of {what}, "
                                 f"{math.degrees(lo):.4g} to {math.degrees(hi):.4g} degrees", param_hint="--q0")


def _within_axis(cfg, given: tuple[bool, bool, bool, bool], lo: float, hi: float, what: str,
                 qd_max: float = math.inf, tau_max: float = math.inf, q0: float | None = None):
    """``cfg`` (a LoopConfig) within the axis ``what``: the simulated start ``q0`` (degrees, :func:`_check_start`)
    and its position window inside the range ``lo``..``hi`` (rad),
    ``--qd-max`` at most the top speed ``qd_max`` (rad/s), ``--tau-max`` at most the drive's torque ``tau_max``
    (N·m; beyond it the torque stop could never trip).  A default beyond is cut to the axis; a value the user gave
    (``given``: --q-min, --q-max, --qd-max, --tau-max) beyond is refused."""
    if q0 is not None:
        _check_start(q0, lo, hi, what)
    L = cfg.limits
    checks = (("--q-min", L.q_min, lo, -1.0, "degrees", "the range of motion", math.degrees),
              ("--q-max", L.q_max, hi, 1.0, "degrees", "the range of motion", math.degrees),
              ("--qd-max", L.qd_max, qd_max, 1.0, "deg/s", "the top speed", math.degrees),
              ("--tau-max", L.tau_max, tau_max, 1.0, "N·m", "the drive torque", float))
    for (name, v, edge, side, unit, of, show), user in zip(checks, given):
        if user and math.isfinite(edge) and side * (v - edge) > 1e-9 * max(1.0, abs(edge)):
            rng = (f"{math.degrees(lo):.4g} to {math.degrees(hi):.4g}" if unit == "degrees" else f"{show(edge):.4g}")
            raise click.BadParameter(f"{show(v):g} {unit} is beyond {of} of {what}, {rng} {unit}", param_hint=name)
    return dataclasses.replace(cfg, limits=dataclasses.replace(L, q_min=max(L.q_min, lo), q_max=min(L.q_max, hi),
                                                               qd_max=min(L.qd_max, qd_max),
                                                               tau_max=min(L.tau_max, tau_max)))


def _check_axis_kind(params: dict, params_path: Path, axis: int, where: str, hint: str = "",
                     error: type | None = None) -> None:
    """A one-axis parameter file drives the axis that moves only if it is a model of that axis:
    revolute (the virtual KR C4's axis and A1..A6 of a KR C4 over KUKAVARPROXY are) and, when the
    file names its axis, the same number.  A model of another axis (EMPS, a prismatic drive of
    95 kg in N) read as N·m and rad makes a meaningless Γr: false detections move the axis."""
    from kukaid.params import check_model_of

    check_model_of(params, str(params_path), joint="revolute",
                   use=f"they cannot drive {where}, a revolute axis (rad, N·m); fit a model of that axis")
    check_model_of(params, str(params_path), axis=axis, use=f"a model of A{params.get('axis')} cannot drive {where}{hint}",
                   error=error)


@click.command("run-admittance")
@click.option("--params", "params_path", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="Parameter file from `kukaid fit` (the identified model used for Γr).")
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="Run log to write (HDF5: axis log + 'control' group with Γr, σ, σ̇, D, mode, metrics).  While the "
                   "robot moves the run is recorded to NAME.partial.h5 beside it (readable if the run is killed), "
                   "which replaces the output when the run has ended; a command that fails leaves the output as it "
                   "was and names the partial file.")
@click.option("--report", type=click.Path(dir_okay=False, path_type=Path), help="Also write a PDF of the run.")
@click.option("--json", "as_json", is_flag=True, help="Print the metrics as JSON on stdout.")
@click.option("--force", is_flag=True, help="Replace an existing run log.")
@click.option("--damping", type=click.Choice(["constant", "adaptive"]), default="constant", show_default=True,
              help="constant D, or the RBF-adapted damping (eqs. 17-22) starting from D.")
@click.option("--D", "D", type=float, default=50.0, show_default=True, help="Damping, N·m·s/rad (> 0).")
@click.option("--I", "I", type=float, default=20.0, show_default=True, help="Inertia of the admittance, kg·m² (> 0).")
@click.option("--D-min", "D_min", type=float, help="adaptive: lower bound of D [0.3 D].")
@click.option("--D-max", "D_max", type=float,
              help="adaptive: upper bound of the network's D [2 D]; to damp an oscillation the stability monitor "
                   "may raise D above it, up to 10 D (logged with when and why).")
@click.option("--threshold", type=float, default=None,
              help="Detection threshold on |Γr|, N·m [5, the paper's; a quarter of a one-axis file's Coulomb "
                   "friction when that is more: an axis with more friction than the paper's A3, e.g. an A2].")
@click.option("--release", type=float,
              help="|Γr| below which a detection ends, N·m [0.3 threshold: once in contact the axis follows "
                   "down to this holding torque].")
@click.option("--duration", type=FloatRange(0.0, MAX_DURATION, min_open=True), default=10.0, show_default=True,
              help="Seconds of admittance control (after the 1-degree initiation move and rest), at most an hour: "
                   "the run is held in memory until it is written (about 3.2 MB per minute; a longer session is "
                   "several runs).")
@click.option("--cycle", type=float, default=0.012, show_default=True,
              help="Control cycle, s (KRC sample time 0.012; the paper's ~0.024 also works).")
@click.option("--cutoff", type=float, default=5.0, show_default=True,
              help="Low-pass of the torque estimate, Hz (the paper's 5 Hz; higher: less loop delay, so firm grips "
                   "need less damping, but a noisier Γr; at least 2 Hz: a lower one reads a push after the hand let go).")
@click.option("--init-move", type=FloatRange(-10.0, 10.0), default=1.0, show_default=True,
              help="Initiation move before control, degrees, either way: it saturates the Maxwell-slip elements "
                   "(eq. 12) and checks the parameter file with nobody touching, so a one-axis file needs at least "
                   "twice its elements' largest break-away displacement (a shorter move is refused; 0: none, robot "
                   "files only).")
# safety (degrees at the edge)
@click.option("--q-min", type=float, help="Position window, lower bound, degrees (sim default: q0 - 90); within the "
                                          "axis's range of motion (kvp: its software limit switches, read first).")
@click.option("--q-max", type=float, help="Position window, upper bound, degrees (sim default: q0 + 90, cut to the "
                                          "axis's range of motion).")
@click.option("--qd-max", type=float, default=QD_MAX_DEG, show_default=True,
              help="Reference speed limit, deg/s (sim: at most the axis's top speed).")
@click.option("--qdd-max", type=float, default=300.0, show_default=True, help="Reference acceleration limit, deg/s².")
@click.option("--tau-max", type=float, default=100.0, show_default=True,
              help="Motion stops when the external torque |Γr| (the model's torque minus the measured one: a push, a "
                   "collision; not the gravity load) exceeds this, N·m (sim: at most the drive's torque).")
@click.option("--max-age", type=float, default=0.1, show_default=True,
              help="Motion stops when the latest measurement is older than this, s, at most 1 (kvp: also the "
                   "longest a reply of KUKAVARPROXY is awaited, at least 2 cycles).")
# backends
@click.option("--backend", type=click.Choice(["sim", "kvp"]), default="sim", show_default=True,
              help="sim: the virtual KR C4 with a simulated operator; kvp: a real KR C4 over KUKAVARPROXY.")
@click.option("--operator", type=click.Choice(["human", "push", "pull", "hand", "none"]), default="human",
              show_default=True,
              help="sim: human (a person's arm: impedance around an intended minimum-jerk move, co-contraction, "
                   "reflex and reaction delays, tremor, lets go on target), push (open-loop 12-18 N·m push) or "
                   "pull/hand (open-loop spring dragging the joint) or none (nobody touches the axis); drawn from --seed.")
@click.option("--grip", type=click.Choice(["soft", "ordinary", "firm"]),
              help="sim, --operator human: the person's grip [drawn from --seed].")
@click.option("--seed", type=click.IntRange(0, 2**32 - 1), default=0, show_default=True,
              help="sim: seed of noise, vibration and operator.")
@click.option("--q0", type=float, default=30.0, show_default=True,
              help="sim: start position, degrees, within the simulated axis's range of motion (A3 of a KR 6 R700 "
                   "sixx: -120 to 156); by default 30, or the middle of the axis's range when 30 is within 40 "
                   "degrees of its end (A2: -72.5).")
@click.option("--sim-config", type=click.Path(dir_okay=False, path_type=Path),
              help="sim, one-axis parameter file: JSON overriding the simulator's truth and settings (the "
                   "simulated axis has the paper's A3 dynamics whatever its number, --axis 2 too: for A2's "
                   "gravity give its Izz and Mx here).")
@click.option("--noise", type=float, help="sim, one-axis parameter file: torque noise sigma, N·m [0.5].")
@click.option("--plant-friction", type=click.Choice(["gms", "lugre"]),
              help="sim, one-axis parameter file: the simulated axis's friction law [gms, the estimator's own: "
                   "Maxwell-slip at rest, Stribeck sliding; lugre: LuGre (stiction, bristles), a law the estimator "
                   "was not built on].")
@click.option("--strict", is_flag=True,
              help="Exit with status 4 when the run completed with warnings (did not settle, a detection with "
                   "nobody touching, the threshold at rest had to rise by over 20 %).")
@click.option("--program", type=click.Path(dir_okay=False, path_type=Path),
              help="sim with a robot parameter file: a robot trajectory (`kukaid excite fourier --robot`) the "
                   "other axes follow meanwhile [they stand at mid range].")
@click.option("--no-rest-model", is_flag=True,
              help="Run a robot parameter file's model although it has no friction model at rest: with nobody "
                   "touching it the axis can move by itself (refused without this flag).")
@click.option("--enable-motion", is_flag=True, help="kvp: really move the robot (required with --backend kvp).")
@click.option("--host", default="127.0.0.1", show_default=True, help="kvp: KUKAVARPROXY host.")
@PORT
@click.option("--axis", type=AXIS, default=3, show_default=True,
              help="Axis to control: kvp (A1..A6), a robot parameter file (any of its axes), or the axis the "
                   "one-axis virtual KR C4 simulates (A1..A6; the one-axis parameter file's: a file of A2 needs "
                   "--axis 2).")
@URDF
def command(params_path: Path, output: Path, report: Path | None, as_json: bool, force: bool, damping: str,
            D: float, I: float, D_min: float | None, D_max: float | None, threshold: float, release: float | None,
            duration: float, cycle: float, cutoff: float, init_move: float, q_min: float | None, q_max: float | None,
            qd_max: float, qdd_max: float, tau_max: float, max_age: float, backend: str, operator: str, seed: int,
            q0: float, grip: str | None, sim_config: Path | None, noise: float | None, plant_friction: str | None,
            strict: bool, program: Path | None, no_rest_model: bool, enable_motion: bool, host: str, port: int,
            axis: int, urdf: Path | None) -> None:
    """Push the axis by hand without a force sensor: estimate the external torque Γr from the
    identified model (eqs. 12-14) and let an admittance (eqs. 15-16) with constant or adaptive
    damping (eqs. 17-22) move the reference, bounded and watched (position window, speed,
    acceleration, measurement age).

    The default backend is the virtual KR C4 with a simulated operator.  A real robot
    (--backend kvp) moves only with --enable-motion and a finite position window, through the
    KRL program of `kukaid krl-follower` (which clamps to its own window and stops when this
    command's heartbeat stops).  A one-axis parameter file without Maxwell-slip elements is
    refused (at rest the axis would move by itself), and so is a robot parameter file unless
    --no-rest-model (it has no friction model at rest at all).  Exit status 3: the run stopped early (the
    log says why); 4 (with --strict): it completed with warnings; Ctrl-C
    or SIGTERM stops it at the next cycle, and the log and report are still written (the
    report's comparison run cut where the run stopped).
    """
    import json

    import numpy as np

    from kukaid.control.loop import THRESHOLD, LoopConfig, check_guidable, default_threshold, run_admittance
    from kukaid.control.metrics import operator_metrics
    from kukaid.control.rbf import RBFConfig
    from kukaid.control.recorder import RunRecorder, check_no_partial
    from kukaid.control.safety import MAX_AGE_LIMIT, SafetyLimits, check_motion_allowed
    from kukaid.errors import KukaidError, OptionError, ParamFileError
    from kukaid.identify.fitted import axis_option
    from kukaid.jsonfile import jsonable
    from kukaid.params import is_robot_params, load_any_params, model_from_params
    from kukaid.atomic import check_writable
    from kukaid_cli._util import (check_noise, check_outputs, check_suffix, given, progress, refuse_overwrite,
                                  require_positive, strict_exit, usage_errors)

    check_suffix(output, ".h5", ".hdf5")
    check_suffix(report, ".pdf")
    check_outputs([output, report], [params_path, sim_config])
    check_noise(noise)
    if grip is not None and operator != "human":
        raise click.UsageError("--grip is for --operator human")
    if backend == "kvp" and axis > 6:
        raise click.BadParameter(f"{axis}: a KR C4 over KUKAVARPROXY moves A1..A6", param_hint="--axis")
    if backend == "kvp":  # the simulator's and the simulated person's options do nothing on a robot
        sim_only = [f"--{k.replace('_', '-')}" for k, v in (("sim_config", sim_config), ("noise", noise),
                                                             ("plant_friction", plant_friction), ("program", program),
                                                             ("grip", grip)) if v is not None]
        sim_only += [f"--{k}" for k in ("operator", "seed", "q0") if given(k)]
        if sim_only:
            raise click.UsageError(f"{', '.join(sim_only)} {'is' if len(sim_only) == 1 else 'are'} for --backend sim "
                                   "(the simulator and its simulated person): a real robot starts where it stands")
    if backend == "sim":  # and the real robot's do nothing on the simulator: a run meant for a robot
        kvp_only = [f"--{k.replace('_', '-')}" for k in ("enable_motion", "host", "port") if given(k)]
        if kvp_only:
            raise click.UsageError(f"{', '.join(kvp_only)} {'is' if len(kvp_only) == 1 else 'are'} for --backend kvp "
                                   "(a real KR C4 over KUKAVARPROXY): without it the run is on the virtual KR C4")
    params = load_any_params(params_path, urdf)
    robot_file = is_robot_params(params)  # a whole robot (`kukaid fit --robot`): Γr of the axis from every axis
    if no_rest_model and not robot_file:
        raise click.UsageError("--no-rest-model is for a robot parameter file (a one-axis file has its model at rest)")
    if robot_file:
        from kukaid.control.robot_residual import RobotTorqueModel

        axis_option(str(params_path), tuple(params["axes"]), axis)
        model = RobotTorqueModel.from_params(params, str(params_path))
    else:
        if given("axis") and params.get("axis") is not None:  # the file's axis, before the robot's or simulator's
            axis_option(str(params_path), (int(params["axis"]),), axis)
        if backend == "kvp":  # A1..A6 of a KR C4, read in degrees: revolute
            _check_axis_kind(params, params_path, axis, f"A{axis} of the KR C4 (--axis {axis})",
                             f"; pass --axis {params.get('axis')} for that axis", error=OptionError)
        model = model_from_params(params)
    rbf = None
    if damping == "adaptive":
        dmin = 0.3 * D if D_min is None else D_min
        dmax = 2.0 * D if D_max is None else D_max
        if not 0 < dmin <= D <= dmax:
            raise click.UsageError(f"need 0 < --D-min ({dmin:g}) <= --D ({D:g}) <= --D-max ({dmax:g})")
        with usage_errors():
            rbf = RBFConfig(D0=D, D_min=dmin, D_max=dmax)
    elif D_min is not None or D_max is not None:
        raise click.UsageError("--D-min/--D-max are for --damping adaptive")

    if backend == "sim":
        if not math.isfinite(q0):
            raise click.BadParameter(f"{q0} is not a position in degrees", param_hint="--q0")
        if not given("q0") and sim_config is None and 1 <= axis <= 6 and (
                not robot_file or params["robot"]["urdf"] == "kr6-r700-sixx"):
            q0 = _default_start(axis)
        lo_deg = q0 - 90.0 if q_min is None else q_min
        hi_deg = q0 + 90.0 if q_max is None else q_max
    else:
        lo_deg = q_min if q_min is not None else -math.inf
        hi_deg = q_max if q_max is not None else math.inf
    _check_window(lo_deg, hi_deg, q0 if backend == "sim" else None, q_min is None or q_max is None)
    lo, hi = math.radians(lo_deg), math.radians(hi_deg)
    limits_given = (q_min is not None, q_max is not None, given("qd_max"), given("tau_max"))
    # SafetyLimits checks these too; here the message names the option
    require_positive(("--qd-max", qd_max), ("--qdd-max", qdd_max), ("--tau-max", tau_max), ("--max-age", max_age))
    if max_age > MAX_AGE_LIMIT:
        raise click.BadParameter(f"{max_age:g} s is above {MAX_AGE_LIMIT:g} s: the robot would move on measurements "
                                 "that old", param_hint="--max-age")
    own = default_threshold(model)
    if threshold is None and THRESHOLD < own >= tau_max:  # raised by the file, not by an option: say whose it is
        raise ParamFileError(f"{params_path}: the default threshold, a quarter of its Coulomb friction Fc "
                             f"{float(model.friction.Fc):g} N·m, is {own:g} N·m, not below the torque limit "
                             f"{tau_max:g} N·m (--tau-max): a file in N·mm? (kukaid show); else give --threshold "
                             "and --tau-max for this axis")
    with usage_errors():  # values of options alone
        limits = SafetyLimits(q_min=lo, q_max=hi, qd_max=math.radians(qd_max), qdd_max=math.radians(qdd_max),
                              tau_max=tau_max, max_age=max_age)
        check_motion_allowed(backend, enable_motion, limits)
        # LoopConfig checks the admittance's stability (also at D-max) and the detection thresholds
        threshold = own if threshold is None else threshold
        cfg = LoopConfig(I=I, D=D, damping=damping, threshold=threshold, release=release, cycle=cycle,
                         sample_time=0.012, duration=duration, init_move=math.radians(init_move), rbf=rbf,
                         cutoff=cutoff, limits=limits, no_rest_model=no_rest_model)

    for p in (output, report):  # after the options' checks: a wrong option is said first
        if p is not None:
            refuse_overwrite(p, force)
            check_writable(p)  # before the robot moves: the record of the run must be writable
    check_no_partial(output)  # a run that was killed or failed: recorded data, never replaced

    def guidable() -> None:  # after the options and the file's axis and kind, before anything moves
        try:
            check_guidable(model, no_rest_model, math.radians(init_move))
        except KukaidError as e:
            raise ParamFileError(f"{params_path}: {str(e).removeprefix('run-admittance: ')}") from None

    attrs = {"params_file": str(params_path), "backend": backend}
    if backend == "sim":
        from kukaid.robot import SimRobot
        from kukaid.sim import SimConfig, VirtualKRC4, load_sim_config
        from kukaid.sim.operator import make_operator, operator_params

        if robot_file and (sim_config is not None or noise is not None or plant_friction is not None):
            raise click.UsageError("--sim-config, --noise and --plant-friction are for one-axis parameter files")
        scfg = load_sim_config(sim_config) if sim_config else SimConfig()
        if noise is not None:
            scfg = scfg.replace(noise_sigma=noise)
        if plant_friction is not None:
            scfg = scfg.replace(friction_law=plant_friction)
        if abs(scfg.sample_time - 0.012) > 1e-9:
            cfg = dataclasses.replace(cfg, sample_time=scfg.sample_time)
        q0r = math.radians(q0)

        if robot_file:  # the six-axis virtual KR C4 of that robot, the other axes standing at their mid range
            from kukaid.sim.robot_plant import RobotSimConfig, VirtualRobotKRC4

            guidable()
            plant = VirtualRobotKRC4(RobotSimConfig(robot=params["robot"]["urdf"]), seed=seed)
            cfg = dataclasses.replace(cfg, sample_time=plant.cfg.sample_time)
            lo_, hi_ = (np.asarray(x, float) for x in (plant.model_nominal.lowerPositionLimit,
                                                       plant.model_nominal.upperPositionLimit))
            q_start = np.where(np.isfinite(lo_) & np.isfinite(hi_), 0.5 * (lo_ + hi_), 0.0)
            prog = None
            if program is not None:
                from kukaid.excite.fourier import RobotTrajectory, load_trajectory

                prog = load_trajectory(program)
                if not isinstance(prog, RobotTrajectory) or tuple(prog.axes) != tuple(range(1, plant.n + 1)):
                    raise KukaidError(f"{program}: not a trajectory of every axis A1..A{plant.n} of the robot")
                q_start = np.asarray(prog.q[0], float).copy()
            urdf_lim = plant.model_nominal
            cfg = _within_axis(cfg, limits_given, float(lo_[axis - 1]), float(hi_[axis - 1]), f"the URDF's A{axis}",
                               float(urdf_lim.velocityLimit[axis - 1]), float(urdf_lim.effortLimit[axis - 1]), q0)
            q_start[axis - 1] = math.radians(q0)
        else:
            if program is not None:
                raise click.UsageError("--program is for a robot parameter file")
            q_start = prog = None
            # the virtual KR C4 simulates one revolute axis: A3, or the one --axis names (as capture simulates the
            # trajectory's), or the one --sim-config says
            if given("axis") and sim_config is None:
                if axis > 6:
                    raise click.BadParameter(f"{axis}: the virtual KR C4 has axes 1 to 6", param_hint="--axis")
                scfg = scfg.replace(axis=axis)
            if given("axis") and axis != scfg.axis:
                raise click.BadParameter(f"{axis}: the virtual KR C4 simulates A{scfg.axis} (a --sim-config's "
                                         "\"axis\" sets another)", param_hint="--axis")
            _check_axis_kind(params, params_path, scfg.axis, f"the virtual KR C4's A{scfg.axis}",
                             f" (--axis {params.get('axis')} simulates that axis)")
            from kukaid.models.limits import AxisLimits

            rng = AxisLimits.kr6_r700_sixx(scfg.axis)
            cfg = _within_axis(cfg, limits_given, rng.q_min, rng.q_max,
                               f"the virtual KR C4's A{scfg.axis} (a KR 6 R700 sixx)", rng.qd_max, scfg.tau_max, q0)
            guidable()

        def sim_backend(cfg_):  # the same person and the same noise for every controller (paired)
            op_ = None if operator == "none" else make_operator(operator, seed, q0r + cfg_.init_move,
                                                                t_start=cfg_.init_time + cfg_.init_rest + 0.8, grip=grip)
            if robot_file:
                return SimRobot(VirtualRobotKRC4(plant.cfg, seed=seed), q_start, op_, program=prog, axis=axis), op_
            return SimRobot(VirtualKRC4(scfg, seed=seed), q0r, op_), op_

        be, op = sim_backend(cfg)
        attrs.update(seed=seed, operator=operator, operator_params=operator_params(op))
        if robot_file:
            attrs.update(robot=params["robot"]["urdf"], truth=plant.truth.to_dict())
            axis_id = axis
        else:
            attrs.update(sim_config=scfg.to_dict(), truth={**scfg.truth_params(), "axis": scfg.axis})
            axis_id = scfg.axis
    else:
        from kukaid.errors import ControllerError
        from kukaid.robot import KvpRobot
        from kukaid.krc.kvp import KvpClient, KvpError

        guidable()
        client = KvpClient(host=host, port=port, timeout=max(max_age, 2 * cycle))
        try:
            client.connect()
            be = KvpRobot(client, axis=axis, n_axes=model.n if robot_file else 0)
            soft = be.soft_limits()  # the controller's software limit switches, before anything moves
        except KvpError as e:  # named as capture names it
            client.close()
            raise ControllerError(f"run-admittance: {e}") from None
        if soft is None:
            click.echo(f"kukaid: warning: run-admittance: $SOFTN_END[{axis}]/$SOFTP_END[{axis}] could not be read: the "
                       f"window [{q_min:g}, {q_max:g}] degrees is not checked against A{axis}'s software limit switches "
                       "(the KRC's own still stop the axis there)", err=True)
        else:
            try:
                cfg = _within_axis(cfg, limits_given, *soft, f"A{axis} (its software limit switches on the controller)")
            except click.BadParameter:
                client.close()
                raise
        be.window = (cfg.limits.q_min, cfg.limits.q_max)  # standing outside it, nothing is switched on
        attrs.update(host=host, port=port)
        axis_id = axis

    # recorded to NAME.partial.h5 while the robot moves; the outputs replaced only when the run has ended
    channels = ("q", "tau", "q_cmd") + (("tau_ext_true",) if backend == "sim" else ())
    lam = cfg.rbf.lam if cfg.rbf is not None else RBFConfig().lam
    notes: list[str] = []
    with RunRecorder(output, axis=axis_id, channels=channels, attrs=attrs, report=report, force=force) as rec:
        with progress(cfg.init_time + cfg.init_rest + cfg.duration, f"run-admittance ({backend})") as update:
            run = rec.record(lambda on_row: run_admittance(rec.guard(be), model, cfg, progress=update, on_row=on_row))

        def metrics() -> None:  # the paper's measures over the fixed window of a human operator
            if backend == "sim":
                run.metrics.update(operator_metrics(run.data, op, lam, scfg.sample_time))

        def draw(path: Path) -> None:
            from kukaid.control.plots import plot_runs

            runs = [(f"{damping} damping" + (f" (D {D:g})" if damping == "constant" else f" (D0 {D:g})"),
                     run.data, run.metrics)]
            if backend == "sim":  # the other controller on the same operator, side by side

                def other_run(cfg2, seen):
                    be2, op2 = sim_backend(cfg2)
                    run2 = run_admittance(rec.guard(be2, seen), model, cfg2)
                    run2.metrics.update(operator_metrics(run2.data, op2, lam, scfg.sample_time))
                    return run2

                compared = rec.comparison(run, cfg, other_run, notes)
                if compared is not None:
                    other, run2, cut = compared
                    label = f"{other} damping (D {D:g}{', for comparison' if other == 'constant' else ''})"
                    runs.append((label + (f", {cut}" if cut else ""), run2.data, run2.metrics))
                    runs.sort(key=lambda r: not r[0].startswith("constant"))
            who = f", operator {operator} seed {seed}" if backend == "sim" else ""
            plot_runs(runs, path, title=f"kukaid run-admittance ({damping} damping, {backend}{who}, "
                                        f"cycle {1000 * cfg.cycle:g} ms)")

        rec.finish(run, metrics=metrics, report=draw)
        if run.metrics.get("ignored_effects"):  # a file refined by diagnose -o: say what Γr went without
            from kukaid.control.torque_residual import SUPPORTED_EFFECTS

            notes.append(f"the parameter file's effects {', '.join(run.metrics['ignored_effects'])} (from kukaid "
                         f"diagnose) are not modelled online, only {', '.join(SUPPORTED_EFFECTS)}: Γr was estimated "
                         "without them")
        # the summary too is printed while the signals are counted: one coming now is not an exit 130
        if as_json:
            for w in [*(run.metrics.get("warnings") or ()), *notes]:  # the JSON holds them too; a person reads stderr
                click.echo(f"kukaid: warning: run-admittance: {w}", err=True)
            click.echo(json.dumps(jsonable(run.metrics)))
        else:
            m = run.metrics
            click.echo(f"run-admittance ({damping} damping, {backend}): {run.status}")
            grip_drawn = getattr(getattr(op, "p", None), "grip", None) if backend == "sim" else None
            if grip_drawn is not None:
                click.echo(f"  {'operator':28s} {operator}, seed {seed}, {grip_drawn} grip")
            for k in ("detection_delay", "residual_rmse", "residual_rmse_dynamic", "residual_rmse_quasi_static",
                      "false_detections", "mean_sq_dgamma", "mean_cost", "displacement", "peak_speed", "D_range",
                      "settled", "clipped_cycles", "xi", "dgamma2", "xi_true", "dgamma2_true", "end_error",
                      "stability_events"):
                if k in m:  # NaN: no such figure for this run (no push, no quasi-static cycle)
                    v = m[k]
                    click.echo(f"  {_LABELS.get(k, k):28s} " + ("n/a" if isinstance(v, float) and math.isnan(v) else
                                                f"{_fmt(v)}{_UNITS.get(k, '')}"))
            for w in m.get("warnings") or ():
                click.echo(f"  warning: {w}")
            for w in notes:
                click.echo(f"  note: {w}")
            click.echo(f"  -> {output}" + (f", {report}" if report else ""))
        if not run.status.startswith("completed"):
            slow = ""
            if backend == "kvp" and "no complete reply" in run.status:  # which option sets that deadline
                slow = (f"; a reply is awaited at most max(--max-age, 2 x --cycle) = {max(max_age, 2 * cycle):g} s: "
                        "a slower link or proxy needs a larger --max-age, which also lets the robot move on "
                        "older measurements")
            click.echo(f"kukaid: error: run-admittance: {run.status} (the run log {output} holds every cycle until "
                       f"then){slow}", err=True)
            raise SystemExit(3)
        if strict:
            strict_exit("run-admittance", run.metrics.get("warnings") or [])
        if rec.interrupts.count > 0 and run.status.startswith("completed"):  # Ctrl-C/SIGTERM after the run had ended
            click.echo(f"kukaid: error: run-admittance: interrupted after the run had completed (the run log {output} "
                       "is complete)", err=True)
            raise SystemExit(3)

