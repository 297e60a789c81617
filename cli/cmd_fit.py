"""kukaid fit: identify an axis from logs and write the parameter file."""
from __future__ import annotations

from pathlib import Path

import click

from kukaid_cli._util import AXIS


@click.command("fit")
@click.argument("logs", nargs=-1, type=click.Path(dir_okay=False, path_type=Path))
@click.option("--friction", "friction", multiple=True, type=click.Path(dir_okay=False, path_type=Path),
              help="Friction experiment log (constant-velocity sweeps); repeatable.")
@click.option("--inertia", "inertia", multiple=True, type=click.Path(dir_okay=False, path_type=Path),
              help="Inertia experiment log (sine); repeatable.")
@click.option("--presliding", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Pre-sliding experiment log (Maxwell-slip elements).")
@click.option("--axis", type=AXIS, default=None,
              help="Axis number (default: the logs' only axis; required for a log of several; not with --robot).")
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="Parameter file to write (JSON: kukaid.params/1, with --robot kukaid.robot_params/1); an existing parameter file of the same kind "
                   "is replaced (fitted parameters are derived from the logs), any other file only with --force.")
@click.option("--force", is_flag=True, help="Replace an existing file that is not a parameter file of this kind.")
@click.option("--json", "as_json", is_flag=True,
              help="Print the parameter file written as JSON on stdout (with \"output\"), not the table.")
@click.option("--method", type=click.Choice(["joint", "staged"]), default="joint", show_default=True,
              help="Stribeck fit: joint (all dynamic samples) or staged (the paper's eqs. 2-5).")
@click.option("--friction-model", type=click.Choice(["auto", "stribeck", "coulomb-viscous"]), default=None,
              help="Friction model [default: auto, Stribeck when the data determine it, else Coulomb-viscous; "
                   "with --robot: coulomb-viscous].")
@click.option("--gravity", type=click.Choice(["cos", "cos+sin", "none"]), default=None,
              help="Gravity terms: Mx cos q, + My sin q, or none [default: cos; none for a prismatic axis].")
@click.option("--offset/--no-offset", default=None,
              help="Fit a constant torque offset [default: no; yes for a prismatic axis, whose gravity is constant].")
@click.option("--elements", type=click.IntRange(1, 10), default=3, show_default=True,
              help="Maxwell-slip elements (with --presliding).")
@click.option("--cutoff", type=float, default=None, help="Low-pass cut-off, Hz (default 5 Hz at KRC rates; --robot: 10 Hz, at most fs/10; with "
                   "--robot and several recordings 5, 10 or 20 Hz chosen by held-out error).")
@click.option("--order", type=click.IntRange(1, 8), default=None, help="Butterworth order (default 3 at KRC rates).")
@click.option("--qd-thr", type=float, default=None, help="Dynamic-mode velocity threshold, rad/s (0.0017).")
@click.option("--edge", type=int, default=None, help="Samples trimmed at both ends (default 5 fs/cutoff).")
@click.option("--decimate", type=click.IntRange(1, 1000), default=None,
              help="Keep every n-th sample after filtering [default: 1; with --robot: about 10 per cut-off period].")
@click.option("--reversal-window", type=float, default=None,
              help="s; dynamic samples this close to a reversal/start/stop are not fitted (default 1.2/cutoff, or 0 "
                   "when the filter smears a jump over a dozen samples or fewer; 0 keeps all).")
@click.option("--diff", type=click.Choice(["central", "spectral"]), default=None,
              help="Differentiation of the filtered position (default central differences).")
@click.option("--bound", "bound", multiple=True, metavar="NAME=LO:HI",
              help="Override a bound, e.g. --bound vs=0.005:0.1 --bound Fs-Fc=0:5 (empty side = unbounded; vs and "
                   "delta above 0).")
@click.option("--robot", default=None, metavar="URDF|NAME",
              help="Fit all axes of a robot jointly from its URDF (or kr6-r700-sixx): base parameters, a "
                   "physically consistent estimate, per-joint friction and offset (kukaid.robot_params/1).")
@click.option("--prior-weight", type=float, default=None,
              help="With --robot: weight of the pull toward the URDF's nominal links [default: 1e-3].")
@click.option("--torque-side", type=click.Choice(["joint", "motor"]), default="joint", show_default=True,
              help="With --robot: the logs' torques are joint-side or motor-side (gear ratios from the URDF).")
@click.option("--stribeck-vs", type=float, default=0.05, show_default=True,
              help="With --robot and --friction-model stribeck: the (fixed) Stribeck velocity, rad/s.")
@click.option("--rotor-inertia/--no-rotor-inertia", default=None,
              help="With --robot: fit one rotor inertia per motor, or not [when the logs' torques come from the "
                   "motor currents: KUKA Trace, KUKAVARPROXY, the virtual KR C4; a link-side torque sensor does not "
                   "see the rotors].")
@click.option("--mass-bounds", default=None, metavar="LO:HI|none",
              help="With --robot: every link's mass within LO-HI times its URDF mass, the total within 0.67-1.5x "
                   "[default: 0.4:2.5]; none: no bounds.")
@click.option("--viscous-beyond", type=click.Choice(["hold", "linear"]), default=None,
              help="With --robot: beyond the fitted speeds the viscous friction is held (hold) or extrapolated "
                   "(linear) [default: hold].")
@click.option("--coupling", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="With --robot --torque-side motor: n x n JSON matrix, motor angles = ratio (I + C) q "
                   "(the coupled wrist drives).")
def command(logs, friction, inertia, presliding, axis, output, force, as_json, method, friction_model, gravity, offset, elements,
            cutoff, order, qd_thr, edge, decimate, reversal_window, diff, bound, robot, prior_weight, torque_side,
            stribeck_vs, rotor_inertia, mass_bounds, viscous_beyond, coupling) -> None:
    """Fit Stribeck friction, Izz/Mx and Maxwell-slip elements from axis logs (HDF5 or CSV);
    with --robot, all axes of a robot jointly from logs of the whole arm moving.

    The table on stdout ends with the parameters that ended on a bound, the pre-processing and why,
    and warnings (IPOPT stopped early; other axes move, so a single-axis model cannot explain this
    one); the parameter file's metrics hold the same (at_bound, warnings, single_axis_adequate)."""
    _check_applicable(click.get_current_context(), robot is not None, presliding is not None)
    from kukaid_cli._util import require_positive

    require_positive(("--cutoff", cutoff), ("--stribeck-vs", stribeck_vs))
    require_positive(("--prior-weight", prior_weight), zero_ok=True)
    if robot is not None:
        _fit_robot(logs, robot, output, force, friction_model, cutoff, order, decimate, prior_weight, torque_side,
                   stribeck_vs, rotor_inertia, coupling, as_json, mass_bounds, viscous_beyond)
        return
    friction_model = friction_model or "auto"
    decimate = decimate or 1

    from kukaid.identify import fit_axis, format_table
    from kukaid.identify.stribeck_fit import check_bound
    from kukaid.params import save_params
    from kukaid.params.axis import SCHEMA
    from kukaid_cli._util import (check_outputs, check_suffix, option_in_data_error, refuse_other_kind, stages,
                                  usage_errors)

    check_suffix(output, ".json")
    check_outputs([output], [*logs, *friction, *inertia, presliding])
    if not (logs or friction or inertia):
        raise click.UsageError("no logs to fit: give general logs (LOG...), or --friction and/or --inertia logs")
    require_positive(("--qd-thr", qd_thr), ("--reversal-window", reversal_window), zero_ok=True)
    if edge is not None and edge < 0:
        raise click.BadParameter(f"{edge} must be >= 0", param_hint="--edge")
    bounds = {}
    for b in bound:
        try:
            name, rng = b.split("=", 1)
            lo, hi = rng.split(":", 1)
            bounds[name.strip()] = (float(lo) if lo.strip() else None, float(hi) if hi.strip() else None)
        except ValueError:
            raise click.BadParameter(f"'{b}': expected NAME=LO:HI, e.g. vs=0.005:0.1", param_hint="--bound") from None
    known = ("Izz", "Mx", "My", "offset", "Fc", "Fv", "Fs-Fc", "vs", "delta")
    for name, (lo, hi) in bounds.items():
        if name not in known:
            raise click.BadParameter(f"{name}: no such parameter (parameters: {', '.join(known)})", param_hint="--bound")
        with usage_errors("--bound"):
            check_bound(name, lo, hi)
    refuse_other_kind(output, force, SCHEMA)  # after the options' checks: a wrong option is said first
    stages("fit")("reading, pre-processing and fitting the logs")
    with option_in_data_error(("--cutoff", cutoff is not None, "filter cut-off"),  # its limit: the log's rate
                              ("--edge", edge is not None, "edge trim")):  # and length
        params = fit_axis(logs=list(logs), friction=list(friction), inertia=list(inertia), presliding=presliding,
                          axis=axis, method=method, friction_model=friction_model, gravity=gravity, offset=offset,
                          n_elements=elements, bounds=bounds or None, cutoff=cutoff, order=order, qd_thr=qd_thr,
                          edge=edge, decimate=decimate, reversal_window=reversal_window, diff=diff)
    save_params(output, params)
    _summary(params, output, as_json, format_table)


#: options of the single-axis fit only, and of the robot fit (--robot) only; the others
#: (-o, --friction-model, --cutoff, --order, --decimate) apply to both
_AXIS_ONLY = ("friction", "inertia", "presliding", "axis", "method", "gravity", "offset", "elements", "qd_thr",
              "edge", "reversal_window", "diff", "bound")
_ROBOT_ONLY = ("prior_weight", "torque_side", "stribeck_vs", "rotor_inertia", "coupling", "mass_bounds",
               "viscous_beyond")


def _check_applicable(ctx: click.Context, with_robot: bool, with_presliding: bool) -> None:
    """An option given that the chosen fit does not use is a usage error, not silently ignored."""
    from kukaid_cli._util import given as was_given

    given = {p.name: _flag(p, ctx.params.get(p.name)) for p in ctx.command.params if was_given(p.name, ctx)}
    p = ctx.params
    if with_robot:
        for name in _AXIS_ONLY:
            if name in given:
                raise click.UsageError(f"option {given[name]} does not apply with --robot (it is for the single-axis "
                                       "fit; the robot fit takes every axis of the logs LOG...)")
        if p["friction_model"] == "auto" and "friction_model" in given:
            raise click.UsageError("option --friction-model auto does not apply with --robot "
                                   "(give coulomb-viscous or stribeck)")
        if "stribeck_vs" in given and p["friction_model"] != "stribeck":
            raise click.UsageError("option --stribeck-vs needs --friction-model stribeck (the Coulomb-viscous "
                                   "model has no Stribeck velocity)")
        if "coupling" in given and p["torque_side"] != "motor" and not p["rotor_inertia"]:
            raise click.UsageError("option --coupling needs --torque-side motor or --rotor-inertia (joint-side "
                                   "torques without rotors do not use the drive coupling)")
        return
    for name in _ROBOT_ONLY:
        if name in given:
            raise click.UsageError(f"option {given[name]} needs --robot (it applies only to the robot fit)")
    if "elements" in given and not with_presliding:
        raise click.UsageError("option --elements needs --presliding (the Maxwell-slip elements are fitted "
                               "on the pre-sliding log)")


def _flag(param: click.Parameter, value) -> str:
    """The option as given: ``--no-x`` for an on/off flag given off."""
    off = getattr(param, "secondary_opts", None)
    return max(off if off and value is False else param.opts or [param.name], key=len)


def _mass_bounds(text: str | None):
    """``LO:HI`` or ``none`` -> ((lo, hi), total bounds) for RobotFitSettings; None: the defaults."""
    from kukaid.identify.robot_fit import MASS_BOUNDS, TOTAL_MASS_BOUNDS

    if text is None:
        return MASS_BOUNDS, TOTAL_MASS_BOUNDS
    if text.strip().lower() == "none":
        return None, None
    try:
        lo, hi = (float(x) for x in text.split(":"))
    except ValueError:
        raise click.BadParameter(f"'{text}': expected LO:HI (e.g. 0.4:2.5) or none", param_hint="--mass-bounds") from None
    if not (0 < lo < 1 < hi < float("inf")):
        raise click.BadParameter(f"'{text}': need 0 < LO < 1 < HI", param_hint="--mass-bounds")
    return (lo, hi), TOTAL_MASS_BOUNDS


def _fit_robot(logs, robot, output, force, friction_model, cutoff, order, decimate, prior_weight, torque_side,
               stribeck_vs, rotor_inertia, coupling, as_json=False, mass_bounds=None, viscous_beyond=None) -> None:
    """``kukaid fit LOG... --robot``: the whole robot, written as kukaid.robot_params/1."""
    from kukaid.identify.adequacy import unit_warnings
    from kukaid.identify.robot_fit import PRIOR_WEIGHT, RobotFitSettings, fit_robot, format_robot_table
    from kukaid.logs import read_log
    from kukaid.models.robot import RobotModel
    from kukaid.params import save_robot_params
    from kukaid.params.robot import SCHEMA
    from kukaid_cli._util import check_outputs, check_suffix, option_in_data_error, refuse_other_kind, stages

    if not logs:
        raise click.UsageError("give at least one log of the robot moving (LOG...)")
    check_suffix(output, ".json")
    check_outputs([output], [*logs, coupling])
    mb, tb = _mass_bounds(mass_bounds)
    settings = RobotFitSettings(cutoff=cutoff, order=order or 4, decimate=decimate,
                                friction=friction_model or "coulomb-viscous", vs=stribeck_vs,
                                prior_weight=PRIOR_WEIGHT if prior_weight is None else prior_weight,
                                torque_side=torque_side, rotor=rotor_inertia, mass_bounds=mb, total_mass_bounds=tb,
                                viscous_beyond=viscous_beyond or "hold")
    refuse_other_kind(output, force, SCHEMA)  # after the options' checks: a wrong option is said first
    model = RobotModel(robot)
    cpl = None
    if coupling is not None:
        import numpy as np

        from kukaid.errors import ParamFileError
        from kukaid.jsonfile import read_json

        cpl = read_json(coupling, ParamFileError, "coupling matrix (JSON)", schemas=())
        try:
            cpl = np.asarray(cpl, dtype=float)
        except (TypeError, ValueError):
            raise ParamFileError(f"{coupling}: must be a {model.n} x {model.n} matrix of numbers") from None
        if cpl.shape != (model.n, model.n) or not np.all(np.isfinite(cpl)):
            raise ParamFileError(f"{coupling}: must be a {model.n} x {model.n} matrix of finite numbers, "
                                 f"got shape {cpl.shape}")
    stage = stages("fit")
    stage("reading the logs")
    data = [read_log(p) for p in logs]
    for w in [w for lg in data for a in lg.axes for w in unit_warnings(lg, a)]:
        click.echo(f"kukaid: warning: fit: {w}", err=True)
    stage(f"fitting A1..A{model.n} of {robot} (base parameters, then the physically consistent estimate)")
    with option_in_data_error(("--cutoff", cutoff is not None, "filter cut-off")):
        params = fit_robot(data, model, settings, coupling=cpl)
    save_robot_params(output, params)
    _summary(params, output, as_json, format_robot_table)


def _summary(params: dict, output, as_json: bool, table) -> None:
    """The fit's figures on stdout: the table, or with --json the parameter file written (with
    ``"output"``: where), so a script reads the figures without parsing text."""
    if as_json:
        from kukaid_cli._util import echo_json

        # the JSON holds them too; a person reads stderr (as run-admittance --json)
        for w in (params.get("metrics") or {}).get("warnings") or ():
            click.echo(f"kukaid: warning: fit: {w}", err=True)
        echo_json({"output": str(output), **params})
    else:
        click.echo(table(params))
    click.echo(f"{output}: parameters written", err=True)
